"""Regenerate the bad-input corpus from the manual's sample input.

    python tests/bad_inputs/make_corpus.py

Every corpus file is the sample input (samples/input.udf) shrunk to a 16^3 mesh, 2 particles
and one step (``tiny_sample``) with one thing broken.  What each file is and the message it
must give are in tests/integration/test_bad_input.py (CORPUS); this script only writes the files.
"""
from __future__ import annotations

import os

HERE = os.path.dirname(os.path.abspath(__file__))
SAMPLE = os.path.join(HERE, "..", "..", "samples", "input.udf")

# the Navier_Stokes_Cahn_Hilliard_FDM part of constitutive_eq (the sample's type):
# {NS_solver}{CH_solver} DX, RHO, ETA, kBT, alpha_v, alpha_o, {Potential}
ONE = "1.00000000000000"
CH = '{"implicit_scheme",{-9.00000000000000,1500}}'
FLUID = f"{CH}{ONE},{ONE},{ONE},0.0,{ONE},{ONE},"
NS = '{{"explicit_scheme",{-9.00000000000000,1000,"OFF",{1.00000000000000,10.0000000000000}}}'
SPEC = '[{2,1.00000000000000,0.0,"NONE","OFF",{0.0,0.0,0.0}{0.0,0.0,0.0}0.0,0.0}]'
USER = "[{{32.000000,32.000000,32.000000}{0.0,0.0,0.0}{0.0,0.0,0.0,0.0}{0.0,0.0,0.0}}]"


def fluid(DX=ONE, RHO=ONE, ETA=ONE, kBT="0.0"):
    return (FLUID, f"{CH}{DX},{RHO},{ETA},{kBT},{ONE},{ONE},")


def tiny_sample() -> str:
    """The sample on a 16^3 mesh with 2 particles, GTS = Num_snap = 1: a valid input that
    runs in well under a second."""
    text = open(SAMPLE).read()
    for old, new in (("mesh:{5,5,5}", "mesh:{4,4,4}"),
                     ("output:{100,10,", "output:{1,1,"),
                     (SPEC.replace("{2,", "{8,"), SPEC)):
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    return text


def edit(*pairs):
    """Replace each ``old`` (first occurrence, which must exist) by ``new``."""
    def f(text):
        for old, new in pairs:
            assert old in text, old
            text = text.replace(old, new, 1)
        return text
    return f


def cut_after(marker, keep=0):
    """Truncate the file ``keep`` characters after the start of ``marker``."""
    def f(text):
        i = text.index(marker)
        return text[:i + keep]
    return f


def user_specify(rows):
    def f(text):
        text = edit(('"uniform_random",', '"user_specify",'))(text)
        body = "".join("{{%s}{0.0,0.0,0.0}{1.0,0.0,0.0,0.0}{0.0,0.0,0.0}}" % r for r in rows)
        return edit((USER, f"[{body}]"))(text)
    return f


def both(*fs):
    def f(text):
        for g in fs:
            text = g(text)
        return text
    return f


# file name -> how it is made from the tiny sample (the text of the file, or a function)
FILES = {
    # --- syntax: truncated, unbalanced, garbage
    "truncated_mid_value.udf": cut_after('LJ_powers:"12:6"', 13),
    "truncated_mid_number.udf": cut_after("A_XI:2.00000000000000", 8),
    "truncated_mid_block.udf": cut_after('"space_align",'),
    "missing_end_data.udf": edit(("\\end{data}", "")),
    "missing_data_block.udf": lambda t: t[:t.index("\\begin{data}")],
    "unbalanced_brace.udf": edit(("mesh:{4,4,4}", "mesh:{4,4,4}}")),
    "empty_file.udf": lambda t: "",
    "binary_garbage.udf": lambda t: "\x00\x01\x02\xff\xfe kapsel \x00",
    "nan_value.udf": edit(("A:4.00000000000000", "A:NaN")),
    # --- types
    "string_for_float.udf": edit(("A:4.00000000000000", 'A:"four"')),
    "float_for_int_mesh.udf": edit(("mesh:{4,4,4}", "mesh:{4,4.5,4}")),
    "float_for_int_gts.udf": edit(("output:{1,1,", "output:{1.5,1,")),
    "number_for_select.udf": edit(('LJ_powers:"12:6"', "LJ_powers:12")),
    "string_for_int_particles.udf": edit((SPEC, SPEC.replace("{2,", '{"two",'))),
    "too_few_values.udf": edit(('gravity:{0.0,"-Y"}', "gravity:{0.0}")),
    "int_infinite.udf": edit(("output:{1,1,", "output:{1e400,1,")),
    "int_out_of_range.udf": edit((SPEC, SPEC.replace("{2,", "{99999999999,"))),
    "unknown_item.udf": edit(("EPSILON:5.0", "EPSILLON:5.0")),
    "missing_item.udf": edit(("A:4.00000000000000\n", "")),
    "duplicate_item.udf": edit(("A:4.00000000000000\n", "A:4.00000000000000\nA:3.0\n")),
    # --- select values
    "unknown_constitutive_eq.udf": edit(('"Navier_Stokes_Cahn_Hilliard_FDM"',
                                         '"Navier_Stokes_Cahn_Hilliard"')),
    "electrolyte_zero_charge.udf": edit(('"Navier_Stokes_Cahn_Hilliard_FDM"',
                                         '"Electrolyte"')),
    "bad_lj_powers.udf": edit(('LJ_powers:"12:6"', 'LJ_powers:"12:7"')),
    "unknown_time_increment.udf": edit(('time_increment:{"auto"', 'time_increment:{"fixed"')),
    "unknown_g_direction.udf": edit(('gravity:{0.0,"-Y"}', 'gravity:{0.0,"+Y"}')),
    # --- includes
    "missing_include.udf": edit(('\\include{"define.udf"}', '\\include{"defines.udf"}')),
    "include_not_udf.udf": edit(('\\include{"define.udf"}', '\\include{"notes.txt"}')),
    "include_cycle.udf": edit(('\\include{"define.udf"}',
                               '\\include{"define.udf"}\n\\include{"include_cycle.udf"}')),
    # --- mesh
    "mesh_npx_zero.udf": edit(("mesh:{4,4,4}", "mesh:{0,4,4}")),
    "mesh_npy_negative.udf": edit(("mesh:{4,4,4}", "mesh:{4,-2,4}")),
    "mesh_npz_too_large.udf": edit(("mesh:{4,4,4}", "mesh:{4,4,40}")),
    "mesh_memory_absurd.udf": edit(("mesh:{4,4,4}", "mesh:{12,12,11}")),
    "mesh_dx_zero.udf": edit(fluid(DX="0.0")),
    # --- fluid
    "eta_negative.udf": edit(fluid(ETA="-1.0")),
    "rho_zero.udf": edit(fluid(RHO="0.0")),
    "kbt_negative.udf": edit(fluid(kBT="-0.5")),
    "eta_infinite.udf": edit(fluid(ETA="1e400")),
    "tolerance_positive.udf": edit((CH, CH.replace("-9.00000000000000", "9.0"))),
    "tolerance_unreachable.udf": edit((CH, CH.replace("-9.00000000000000", "-300"))),
    "dx_huge_auto_dt_zero.udf": edit(fluid(DX="1e300")),
    "maximum_iteration_zero.udf": edit((CH, CH.replace("1500", "0"))),
    # --- time and output
    "factor_negative.udf": edit(('time_increment:{"auto",{1.00000000000000}',
                                 'time_increment:{"auto",{-1.0}')),
    "delta_t_zero.udf": edit(('time_increment:{"auto",{1.00000000000000}{1.73839000000000e-009}',
                              'time_increment:{"manual",{1.00000000000000}{0.0}')),
    "delta_t_unstable.udf": edit(('time_increment:{"auto",{1.00000000000000}{1.73839000000000e-009}',
                                  'time_increment:{"manual",{1.00000000000000}{100.0}')),
    "gts_zero.udf": edit(("output:{1,1,", "output:{0,1,")),
    "num_snap_negative.udf": edit(("output:{1,1,", "output:{1,-3,")),
    "num_snap_zero.udf": edit(("output:{1,1,", "output:{1,0,")),
    # --- particles
    "a_zero.udf": edit(("A:4.00000000000000", "A:0.0")),
    "a_xi_negative.udf": edit(("A_XI:2.00000000000000", "A_XI:-2.0")),
    "mass_ratio_zero.udf": edit((SPEC, SPEC.replace("{2,1.00000000000000,", "{2,0.0,"))),
    "particle_number_negative.udf": edit((SPEC, SPEC.replace("{2,", "{-1,"))),
    "particle_larger_than_box.udf": edit(("A:4.00000000000000", "A:9.0")),
    "too_many_particles.udf": edit((SPEC, SPEC.replace("{2,", "{200,"))),
    "user_specify_missing_data.udf": user_specify([]),
    "user_specify_too_few.udf": user_specify(["4.0,4.0,4.0"]),
    "user_specify_overlap.udf": user_specify(["4.0,4.0,4.0", "5.0,4.0,4.0"]),
    "pin_without_particles.udf": edit((SPEC, SPEC.replace("{2,", "{0,")),
                                      ('"NO",\n  {\n   [2 ]', '"YES",\n  {\n   [2 ]')),
    "pin_id_out_of_range.udf": edit(('"NO",\n  {\n   [2 ]', '"YES",\n  {\n   [5 ]')),
    "random_walk_negative.udf": edit(('"uniform_random",\n  {100}',
                                      '"random_walk",\n  {-100}')),
    # --- several problems at once, each on its own line at its value
    "several_problems.udf": edit(("mesh:{4,4,4}", "mesh:{0,4,4}"),
                                 ("A:4.00000000000000", "A:0.0"),
                                 ("output:{1,1,", "output:{0,1,")),
    # --- unsupported features, named together in one line
    "unsupported_together.udf": edit(('"Navier_Stokes_Cahn_Hilliard_FDM"', '"Electrolyte"'),
                                     (SPEC, SPEC.replace('"OFF"', '"TUMBLER"'))),
    # --- resume
    "continue_without_saved_data.udf": edit(('"NEW",', '"CONTINUE_FDM_PHASE_SEPARATION",')),
    # --- command line (valid input, bad flags: see the table in test_bad_input.py)
    "cli_define_missing.udf": lambda t: t,
    "cli_define_not_a_schema.udf": lambda t: t,
    "cli_output_dir_missing.udf": lambda t: t,
    "cli_output_dir_is_a_file.udf": lambda t: t,
    "cli_restart_dir_missing.udf": lambda t: t,
}

SUPPORT = {"notes.txt": "These are notes, not a UDF file.\nmesh = 4 x 4 x 4\n"}


def write_all(directory: str = HERE) -> list:
    base = tiny_sample()
    written = []
    for name, make in FILES.items():
        text = make(base)
        with open(os.path.join(directory, name), "w", encoding="latin-1") as fh:
            fh.write(text)
        written.append(name)
    for name, text in SUPPORT.items():
        with open(os.path.join(directory, name), "w") as fh:
            fh.write(text)
    return written


if __name__ == "__main__":
    print(f"{len(write_all())} corpus files written to {HERE}")
