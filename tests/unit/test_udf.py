"""The UDF language: every fixture parses, read-write-read keeps every value, the
UDFManager API, and one clear message (file:line:col or path) for each error class."""
import glob
import os

import numpy as np
import pytest

from udf import UDFError, UDFManager

from builders import copy_schema, TESTS


HERE = TESTS
SHARED = os.path.join(HERE, "..", "..", "shared", "kapsel-udf")
SAMPLES = os.path.join(HERE, "..", "samples")
FIXTURES = sorted(glob.glob(os.path.join(SAMPLES, "*.udf"))
                  + glob.glob(os.path.join(SAMPLES, "kapsel-udf", "*", "*.udf")))  # copies of
# every real input in ../shared/kapsel-udf (define.udf versions 3.02 to 4.1)
DEFINE = os.path.join(SAMPLES, "define.udf")


def same(a, b):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b))
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b and type(a) is type(b)


@pytest.mark.parametrize("path", FIXTURES, ids=lambda p: os.path.relpath(p, SAMPLES))
def test_fixture_parses_and_round_trips(path, tmp_path):
    u = UDFManager(path)
    if os.path.basename(path) == "kapsel_unit.udf":
        assert "[tau]=[mass^0.5*L*epsilon^-0.5]" in u.text()  # the unit block is kept
    else:
        assert u.schema.global_items  # every other fixture has (or includes) definitions
    out = tmp_path / "copy.udf"
    u.write(str(out))
    v = UDFManager(str(out))
    assert v.text() == u.text()
    assert set(v.common) == set(u.common)
    for name in u.common:
        assert same(u.common[name], v.common[name]), name
    assert v.totalRecord() == u.totalRecord()


def test_v302_define_continues_strings_with_a_backslash(tmp_path):
    """OCTA's v3.02 define.udf (Examples 01-10) continues a description with a backslash at
    the end of the line; the string is joined and every later line number stays right."""
    u = UDFManager(os.path.join(SAMPLES, "kapsel-udf", "ex02", "define.udf"))
    sw = u.schema.item("switch")[0].type
    dist = sw.members[sw.index("INIT_distribution")].type
    desc = dist.members[dist.index("type")].description
    assert desc.startswith("uniform_random:distributed uniformly in box,\trandom_walk:")
    assert "\\" not in desc and "\n" not in desc
    f = tmp_path / "bad.udf"
    f.write_text('\\begin{def}\n a: string "one \\\n two"\n b: int "x\n\\end{def}\n')
    with pytest.raises(UDFError) as e:
        UDFManager(str(f))
    assert e.value.line == 4   # the line of the unclosed string, after the continued one


def test_sample_values():
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    assert u.get("constitutive_eq.type") == "Navier_Stokes_Cahn_Hilliard_FDM"
    assert u.get("mesh") == [5, 5, 5]
    assert u.get("constitutive_eq.Navier_Stokes_Cahn_Hilliard_FDM.CH_solver.type") == \
        "implicit_scheme"
    assert u.get("constitutive_eq.Navier_Stokes_Cahn_Hilliard_FDM.CH_solver."
                 "implicit_scheme.maximum_iteration") == 1500
    assert u.get("object_type.spherical_particle.Particle_spec[0].Particle_number") == 8
    assert u.get("object_type.spherical_particle.Particle_spec[].MASS_RATIO") == [1.0]
    assert u.size("object_type.spherical_particle.Particle_spec[]") == 1
    assert u.get("switch.INIT_distribution.user_specify.Particles[0].R") == [32.0, 32.0, 32.0]
    assert u.get("switch.pin.YES.pin[]") == [2]
    assert u.get("switch.pin.YES.pin_rot[]") == []
    assert u.get("time_increment.manual.delta_t") == pytest.approx(1.73839e-9)
    assert u.get("output.ON.EXTENDED.Print_field.YES.Slab_x") == [0, 8, 4]
    assert u.get("Unit_Parameter.Temperature") == 473.15
    assert isinstance(u.get("mesh.NPX"), int)


def test_records_put_get_size(tmp_path):
    u = UDFManager(schema_from=DEFINE)
    assert u.totalRecord() == 0
    for r in range(3):
        assert u.newRecord(f"rec {r}") == r
        u.put(0.5 * r, "t")
        P = np.arange(5 * 34, dtype=float).reshape(5, 34) + r
        u.put(P, "Particles[]")
    u.put([1.0, 2.0, 3.0], "Particles[].R", [4])
    u.put(9.0, "Particles[2].v.y")
    path = tmp_path / "out.udf"
    u.write(str(path))
    v = UDFManager(str(path))
    assert v.totalRecord() == 3
    assert v.jump(2) == 2
    assert v.get("t") == 1.0
    assert v.get("Particles[4].R") == [1.0, 2.0, 3.0]
    assert v.get("Particles[].R", [4]) == [1.0, 2.0, 3.0]
    assert v.get("Particles[2].v.y") == 9.0
    assert v.size("Particles[]") == 5
    assert v.getArray("Particles[].R").shape == (5, 3)
    assert v.get("Particles[].q.q0") == [9.0 + 2 + 34 * i for i in range(5)]
    v.jump(0)
    assert v.get("t") == 0.0
    v.eraseRecord(0, 2)
    assert v.totalRecord() == 1
    v.jump(-1)
    with pytest.raises(UDFError, match="jump to a record"):
        v.get("t")


def test_put_appends_and_grows(tmp_path):
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    n = u.size("switch.INIT_distribution.user_specify.Particles[]")
    u.put([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
          "switch.INIT_distribution.user_specify.Particles[]", [n])
    assert u.size("switch.INIT_distribution.user_specify.Particles[]") == n + 1
    u.put(7, "switch.pin.YES.pin[]", [1])
    assert u.get("switch.pin.YES.pin[]") == [2, 7]


def test_double_precision_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(3)
    U = rng.standard_normal((8, 8, 8, 3)) * 10.0 ** rng.integers(-12, 12, size=(8, 8, 8, 3))
    u = UDFManager(schema_from=DEFINE)
    u.put("CONTINUE_FDM", "resume.Calculation")
    u.put(U, "resume.CONTINUE_FDM.Saved_Data.U[]")
    u.write(str(tmp_path / "r.udf"))
    v = UDFManager(str(tmp_path / "r.udf"))
    assert np.array_equal(v.getArray("resume.CONTINUE_FDM.Saved_Data.U[]"), U)


def test_put_hands_an_array_over_without_a_copy_when_asked(tmp_path):
    """put(..., copy=False) keeps the caller's float64 array (a restart's fields: no second
    copy of hundreds of MB, issue 25); the default put copies it, so a later change of the
    caller's array does not reach the document."""
    U = np.arange(8 * 8 * 8 * 3, dtype=float).reshape(8, 8, 8, 3)
    path = "resume.CONTINUE_FDM.Saved_Data.U[]"
    u = UDFManager(schema_from=DEFINE)
    u.put("CONTINUE_FDM", "resume.Calculation")
    u.put(U, path)
    U[0, 0, 0, 0] = -1.0
    assert u.getArray(path)[0, 0, 0, 0] == 0.0
    u.put(U, path, copy=False)
    U[0, 0, 0, 1] = -2.0
    u.write(str(tmp_path / "r.udf"))
    v = UDFManager(str(tmp_path / "r.udf"))
    got = v.getArray(path)
    assert got[0, 0, 0, 0] == -1.0 and got[0, 0, 0, 1] == -2.0


def test_single_precision_records():
    u = UDFManager(schema_from=DEFINE)
    u.single_precision_records = True
    u.newRecord()
    u.put(np.full((2, 34), 1.0 / 3.0), "Particles[]")
    assert "0.33333334" in u.text() and "0.3333333333" not in u.text()


def test_writing_nan_is_refused(tmp_path):
    u = UDFManager(schema_from=DEFINE)
    u.newRecord()
    P = np.zeros((2, 34))
    P[1, 3] = np.nan
    u.put(P, "Particles[]")
    with pytest.raises(UDFError, match="NaN"):
        u.write(str(tmp_path / "bad.udf"))
    assert not (tmp_path / "bad.udf").exists()


# ---------------------------------------------------------------- error classes
def broken_copy(tmp_path, old, new):
    copy_schema(tmp_path)
    text = open(os.path.join(SAMPLES, "input.udf")).read()
    assert old in text
    p = tmp_path / "input.udf"
    p.write_text(text.replace(old, new, 1))
    return str(p)


def error_of(path):
    with pytest.raises(UDFError) as e:
        UDFManager(path)
    return str(e.value)


def test_error_malformed_file(tmp_path):
    msg = error_of(broken_copy(tmp_path, "A_XI:2.00000000000000", "A_XI:2.0.0 }"))
    assert "input.udf:" in msg and "unexpected" in msg
    line = int(msg.split("input.udf:")[1].split(":")[0])
    assert open(tmp_path / "input.udf").read().splitlines()[line - 1].startswith("A_XI")


def test_error_truncated_file(tmp_path):
    p = tmp_path / "input.udf"
    copy_schema(tmp_path)
    p.write_text(open(os.path.join(SAMPLES, "input.udf")).read()[:1500])
    msg = error_of(str(p))
    assert "input.udf" in msg and ("end of file" in msg or "unexpected" in msg)


def test_error_wrong_type(tmp_path):
    msg = error_of(broken_copy(tmp_path, "mesh:{5,5,5}", 'mesh:{5,"five",5}'))
    assert "input.udf:" in msg and "mesh.NPY" in msg and "expected a number" in msg
    assert '"five"' in msg


def test_error_wrong_integer(tmp_path):
    msg = error_of(broken_copy(tmp_path, "mesh:{5,5,5}", "mesh:{5,5.5,5}"))
    assert "mesh.NPY" in msg and "integer" in msg


def test_error_unknown_select(tmp_path):
    """A select value outside its choices is refused when it is read, at the value itself:
    an unused branch of an input may hold a stale one (ex12)."""
    u = UDFManager(broken_copy(tmp_path, 'LJ_powers:"12:6"', 'LJ_powers:"11:5"'))
    assert u.get("mesh.NPX") == 5
    with pytest.raises(UDFError) as e:
        u.get("LJ_powers")
    msg = str(e.value)
    assert "LJ_powers" in msg and "'11:5'" in msg and "12:6" in msg
    assert "input.udf:24:11:" in msg


def test_unused_branch_may_hold_a_stale_select(tmp_path):
    """ex12: switch.multipole.ON.Dipole.ON.FIXED.dir is "" (not X, Y or Z); reading the
    branch says so, reading anything else works."""
    u = UDFManager(os.path.join(SAMPLES, "kapsel-udf", "ex12",
                                "a2_N65_Rer025_dipole_mirror.udf"))
    assert u.get("switch.multipole.type") == "ON"
    assert u.get("mesh") == [6, 6, 5]
    for path in ("switch.multipole.ON.Dipole.ON.FIXED.dir", "switch.multipole.ON",
                 "switch"):
        with pytest.raises(UDFError, match=r"a2_N65_Rer025_dipole_mirror.udf:59:36: unknown "
                                           r"choice ''; allowed: X, Y, Z"):
            u.get(path)


def test_every_problem_of_a_file_at_once(tmp_path):
    text = open(broken_copy(tmp_path, "A:4.00000000000000", 'A:"four"')).read()
    text = text.replace("A_XI:2.00000000000000", "A_XI:\"2.0\"").replace("EPSILON:", "EPSILLON:")
    (tmp_path / "input.udf").write_text(text)
    msg = error_of(str(tmp_path / "input.udf"))
    lines = msg.splitlines()
    assert len(lines) == 3, msg
    assert "expected a number" in msg and "'EPSILLON' is not defined" in msg


def test_value_positions():
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    f, line, col = u.value_where("mesh.NPY")
    assert (line, col) == (25, 9) and f.endswith("input.udf")
    assert u.value_where("object_type.spherical_particle.Particle_spec[0].MASS_RATIO")[1:] \
        == (11, 7)


def test_get_of_an_absent_item_says_it_is_absent(tmp_path):
    """OCTA's UDFManager reads data the file holds; a file that is only the schema (an
    output.udf of \\include{"define.udf"}) has none: get() says so instead of returning a
    made-up default.  put() creates the item."""
    copy_schema(tmp_path)
    (tmp_path / "o.udf").write_text('\\include{"define.udf"}\n')
    u = UDFManager(str(tmp_path / "o.udf"))
    with pytest.raises(UDFError, match="'mesh' is absent"):
        u.get("mesh.NPX")
    u.put(6, "mesh.NPX")
    assert u.get("mesh.NPX") == 6


def test_error_wrong_count(tmp_path):
    msg = error_of(broken_copy(tmp_path, "gravity:{0.0,\"-Y\"}", "gravity:{0.0}"))
    assert "gravity" in msg and "expected 2 values" in msg


def test_error_missing_include(tmp_path):
    p = tmp_path / "input.udf"
    p.write_text(open(os.path.join(SAMPLES, "input.udf")).read())
    msg = error_of(str(p))
    assert "define.udf" in msg and "not found" in msg and "input.udf:3" in msg


def test_error_unknown_item(tmp_path):
    msg = error_of(broken_copy(tmp_path, "A_XI:2.00000000000000", "B_XI:2.0"))
    assert "'B_XI'" in msg and "not defined" in msg


def test_error_missing_file(tmp_path):
    msg = error_of(str(tmp_path / "nope.udf"))
    assert "nope.udf" in msg and "cannot read" in msg


def test_error_bad_path():
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    for path, text in [("mesh.NPW", "no member 'NPW'"),
                       ("nosuch.x", "no such item 'nosuch'"),
                       ("object_type.spherical_particle.Particle_spec[3].MASS_RATIO",
                        "out of range"),
                       ("object_type.spherical_particle.Particle_spec.MASS_RATIO",
                        "give an index"),
                       ("mesh..NPX", "malformed path")]:
        with pytest.raises(UDFError) as e:
            u.get(path)
        assert text in str(e.value), (path, str(e.value))
    with pytest.raises(UDFError, match="expected an integer"):
        u.put("five", "mesh.NPX")
    with pytest.raises(UDFError, match="not one of"):
        u.put("bogus", "LJ_powers")


def _spoiled_bulk_array(tmp_path, offset, bad):
    """A record of 100 particles written, then the first 1.0 of the line ``offset`` lines into
    the array replaced by ``bad``: (the reader's message, that line's index)."""
    u = UDFManager(schema_from=DEFINE)
    u.newRecord()
    u.put(np.ones((100, 34)), "Particles[]")
    path = tmp_path / "o.udf"
    u.write(str(path))
    lines = path.read_text().splitlines()
    k = next(i for i, l in enumerate(lines) if l.startswith("{{1.0") and i > 5) + offset
    lines[k] = lines[k].replace("1.0", bad, 1)
    path.write_text("\n".join(lines) + "\n")
    return error_of(str(path)), k


def test_error_in_bulk_array_points_at_the_number(tmp_path):
    msg, k = _spoiled_bulk_array(tmp_path, 10, "1.0x0")
    assert f"o.udf:{k + 1}:" in msg and "x0" in msg


def test_ragged_bulk_array_is_refused(tmp_path):
    u = UDFManager(schema_from=DEFINE)
    u.newRecord()
    u.put(np.ones((10, 10, 10)), "PSI[]")
    text = u.text().replace("{1.0}]", "]", 1)
    p = tmp_path / "o.udf"
    p.write_text(text)
    msg = error_of(str(p))
    assert "PSI" in msg and ("ragged" in msg or "fill" in msg)


def test_error_malformed_number_inside_numeric_text(tmp_path):
    msg, k = _spoiled_bulk_array(tmp_path, 20, "1.0.0")
    assert f"o.udf:{k + 1}:" in msg and "'1.0.0'" in msg and "malformed number" in msg


def test_get_with_unit_conversion():
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    # [L] = Unit_Parameter.Length = 57.5 nm (kapsel_unit.udf)
    assert u.get("constitutive_eq.Navier_Stokes.DX", "[nm]") == pytest.approx(57.5)
    assert u.get("switch.INIT_distribution.user_specify.Particles[0].R", "[nm]") == \
        pytest.approx([32 * 57.5] * 3)
    # [eta] = [mass/(L*tau)], mass = rho L^3, tau = mass^0.5 L epsilon^-0.5, epsilon = kB T
    kB, T, L, rho = 1.3806503e-23, 473.15, 57.5e-9, 1188.0
    mass = rho * L ** 3
    tau = mass ** 0.5 * L / (kB * T) ** 0.5
    assert u.get("constitutive_eq.Navier_Stokes.ETA", "[Pa*s]") == \
        pytest.approx(mass / (L * tau), rel=1e-9)
    with pytest.raises(UDFError, match="different dimensions"):
        u.get("constitutive_eq.Navier_Stokes.DX", "[s]")


def test_two_process_paths_give_identical_results(tmp_path, monkeypatch):
    import udf.manager as M
    import udf.parser as P
    u = UDFManager(schema_from=DEFINE)
    rng = np.random.default_rng(4)
    for r in range(10):
        u.newRecord(f"r{r}")
        u.put(float(r), "t")
        u.put(rng.standard_normal((50, 34)), "Particles[]")
    u.write(str(tmp_path / "serial.udf"))
    monkeypatch.setattr(M, "PARALLEL_WRITE_NUMBERS", 100)
    u.write(str(tmp_path / "parallel.udf"))
    assert (tmp_path / "serial.udf").read_bytes() == (tmp_path / "parallel.udf").read_bytes()
    monkeypatch.setattr(P, "PARALLEL_BYTES", 1000)
    v = UDFManager(str(tmp_path / "parallel.udf"))
    assert v.totalRecord() == 10
    for r in range(10):
        v.jump(r)
        assert np.array_equal(v.getArray("Particles[]"), u.records[r].values["Particles"])
    # a malformed number in the half parsed by the forked child is still pinpointed
    lines = (tmp_path / "parallel.udf").read_text().splitlines()
    k = len(lines) - 5
    lines[k] = lines[k].replace("e", "e+e", 1) if "e" in lines[k] else \
        lines[k].replace(".", "..", 1)
    (tmp_path / "bad.udf").write_text("\n".join(lines) + "\n")
    with pytest.raises(UDFError) as e:
        UDFManager(str(tmp_path / "bad.udf"))
    assert f"bad.udf:{k + 1}:" in str(e.value)


def test_large_arrays_are_written_in_blocks_with_the_same_bytes(monkeypatch):
    """udf.writer formats arrays of more than CHUNK_NUMBERS numbers in blocks of rows (a
    restart's velocity field: 1.13 -> 0.32 GB of work memory at 128 x 128 x 256); the text
    is byte for byte that of one pass, for any block size and number of dimensions."""
    import numpy as np
    import udf.writer as W
    from udf.schema import Primitive
    rng = np.random.default_rng(1)
    t = Primitive("double")
    for shape, ndim in (((37,), 1), ((9, 7), 2), ((5, 4, 3), 3), ((2, 5, 4, 3), 4),
                        ((1, 3, 4, 6), 4)):
        arr = rng.normal(size=shape)
        monkeypatch.setattr(W, "CHUNK_NUMBERS", 1 << 40)
        whole = W.format_value(arr, t, ndim)
        for c in (1, 2, 5, 13):
            monkeypatch.setattr(W, "CHUNK_NUMBERS", c)
            assert W.format_value(arr, t, ndim) == whole, (shape, c)


def test_large_array_text_is_written_block_by_block(monkeypatch):
    """write_pieces forms a large array's blocks one at a time (udf.writer._Blocks): the
    work memory of writing a 2^21-number field (about 40 MB of text) is that of one block
    (about 7 bytes per byte of its text: 2^16 numbers here), not the whole text's, and the
    bytes are those of the joined text."""
    import hashlib
    import tracemalloc
    import numpy as np
    import udf.writer as W
    from udf.schema import Primitive
    arr = np.random.default_rng(2).normal(size=(128, 128, 128))
    t = Primitive("double")
    monkeypatch.setattr(W, "CHUNK_NUMBERS", 1 << 16)

    class Sink:              # a file that keeps only a hash of what it is given
        def __init__(self):
            self.n, self.h = 0, hashlib.sha256()

        def write(self, b):
            self.n += len(b)
            self.h.update(b)

    # and a field whose first axis is short (two species of 2^20 numbers each: rows larger
    # than a block are split in turn)
    for arr, ndim in ((arr, 3), (arr.reshape(2, 64, 128, 128), 4)):
        pieces = []
        W._emit(pieces, arr, t, ndim, False)
        fh = Sink()
        tracemalloc.start()
        W.write_pieces(fh, pieces)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert peak < 0.5 * fh.n, (ndim, peak, fh.n)
        text = "".join(map(str, pieces)).encode()
        assert fh.h.digest() == hashlib.sha256(text).digest()


def test_a_file_read_again_is_parsed_again_only_when_it_or_an_include_changed(tmp_path):
    """udf.parser keeps the parses of a process (define.udf is read by the input's check and
    by both writers): a file read again unchanged gives a fresh copy of the first parse; a
    change of the file or of a file it includes is read, not the copy."""
    from udf import parser
    copy_schema(tmp_path)
    o = tmp_path / "o.udf"
    o.write_text('\\include{"define.udf"}\n\\begin{data}\nmesh:{4,5,6}\n\\end{data}\n')
    first = UDFManager(str(o))
    assert first.get("mesh.NPX") == 4
    first.put(7, "mesh.NPX")                               # a change of one document
    again = UDFManager(str(o))
    assert again.get("mesh.NPX") == 4                      # not seen by the next one
    assert any(k[0] == os.path.normpath(str(o)) for k in parser._PARSED)
    o.write_text('\\include{"define.udf"}\n\\begin{data}\nmesh:{3,5,6}\n\\end{data}\n')
    assert UDFManager(str(o)).get("mesh.NPX") == 3         # the file changed
    d = tmp_path / "define.udf"
    d.write_text(d.read_text().replace("NPX: int", "NPQ: int", 1))
    with pytest.raises(UDFError, match="NPX"):             # its include changed
        UDFManager(str(o)).get("mesh.NPX")
