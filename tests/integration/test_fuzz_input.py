"""Fuzzing the input: the sample input (shrunk to a 16^3 mesh, 2 particles, one step) with
one or two random edits -- a token or line deleted, duplicated or replaced, a number's sign
flipped or the number made huge / zero / NaN / a string, the file truncated -- either runs,
or is refused cleanly: exit 2, one line per problem on stderr, no traceback, nothing written.  A run
that starts and then fails (exit 1: e.g. gravity so strong the CFL limit breaks at step 1)
must also say so in one line without a traceback; it keeps the snapshot files by design.

Runs are kept cheap by a memory budget of 0.25 GB ($KAPSEL_PY_MEMORY_LIMIT_GB, so mutated
meshes are refused by the sanity limit rather than run) and at most 2 steps per run.
KAPSEL_FUZZ_EXAMPLES=n runs more examples; KAPSEL_FUZZ_RANDOM=1 draws new ones each time."""
import contextlib
import io
import os
import re
import signal
import sys
import tempfile
import traceback
import warnings

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from kapsel import cli, config, models  # noqa: F401  (models register their types)

from builders import copy_schema, TESTS


HERE = TESTS
SAMPLES = os.path.join(HERE, "..", "samples")
sys.path.insert(0, os.path.join(HERE, "bad_inputs"))
import make_corpus  # noqa: E402

BASE = make_corpus.tiny_sample()
LINES = BASE.splitlines(keepends=True)
TOKEN = re.compile(r'"[^"\n]*"|[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[A-Za-z_\\]\w*|\S')
TOKENS = [m.span() for m in TOKEN.finditer(BASE)]
NUMBERS = [s for s in TOKENS if re.fullmatch(r"[-+]?[\d.]+(?:[eE][-+]?\d+)?", BASE[s[0]:s[1]])]
STRINGS = [s for s in TOKENS if BASE[s[0]] == '"']
WORDS = sorted({BASE[a:b] for a, b in STRINGS})
ODD_NUMBERS = ["1e300", "-1e300", "1e400", "0", "0.0", "-0.0", "NaN", "inf", '"x"', "1e-300",
               "99999999999999999999", "2147483648", "4.5", "-1", "3", "100000"]
MAX_STEPS = 2
SECONDS_PER_RUN = 30


def splice(text, span, new):
    return text[:span[0]] + new + text[span[1]:]


@st.composite
def one_edit(draw, text):
    """One edit of ``text`` (always positions of the base text, which edits keep valid
    as long as they are applied back to front: see ``mutated``)."""
    kind = draw(st.sampled_from(["delete_token", "duplicate_token", "replace_token",
                                 "delete_line", "duplicate_line", "flip_sign", "odd_number",
                                 "swap_string", "truncate"]))
    if kind in ("delete_token", "duplicate_token", "replace_token"):
        a, b = draw(st.sampled_from(TOKENS))
        tok = BASE[a:b]
        if kind == "delete_token":
            return (a, b, "")
        if kind == "duplicate_token":
            return (a, b, tok + tok)
        c, d = draw(st.sampled_from(TOKENS))
        return (a, b, BASE[c:d])
    if kind in ("delete_line", "duplicate_line"):
        i = draw(st.integers(0, len(LINES) - 1))
        a = sum(len(x) for x in LINES[:i])
        b = a + len(LINES[i])
        return (a, b, "" if kind == "delete_line" else LINES[i] * 2)
    if kind == "flip_sign":
        a, b = draw(st.sampled_from(NUMBERS))
        tok = BASE[a:b]
        return (a, b, tok[1:] if tok.startswith("-") else "-" + tok)
    if kind == "odd_number":
        a, b = draw(st.sampled_from(NUMBERS))
        return (a, b, draw(st.sampled_from(ODD_NUMBERS)))
    if kind == "swap_string":
        a, b = draw(st.sampled_from(STRINGS))
        return (a, b, draw(st.sampled_from(WORDS)))
    return (draw(st.integers(0, len(BASE))), len(BASE), "")   # truncate


@st.composite
def mutated(draw):
    edits = draw(st.lists(one_edit(BASE), min_size=1, max_size=2))
    text = BASE
    done = []
    for a, b, new in sorted(edits, key=lambda e: -e[0]):   # back to front: spans stay valid
        if any(a < d and c < b or a == c for c, d, _ in done):
            continue                                        # overlapping edits: keep one
        text = splice(text, (a, b), new)
        done.append((a, b, new))
    return text, done


def listing(d):
    return sorted(os.path.relpath(os.path.join(r, f), d) for r, ds, fs in os.walk(d)
                  for f in fs + ds)


class TooSlow(Exception):
    pass


def on_alarm(signum, frame):
    raise TooSlow(f"a run took more than {SECONDS_PER_RUN} s")


def run_cli(text, d):
    copy_schema(d)
    with open(os.path.join(d, "input.udf"), "w", encoding="utf-8") as fh:
        fh.write(text)
    before = listing(d)
    err, out = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(d)
    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, SECONDS_PER_RUN)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out), \
                warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            code = cli.main(["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                             "--seed", "1", "--quiet"])
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
        os.chdir(cwd)
    return code, err.getvalue(), out.getvalue(), before, listing(d), caught


@pytest.fixture(autouse=True)
def cheap_runs(monkeypatch):
    monkeypatch.setenv(config.MEMORY_ENV, "0.25")
    real = config.Output.total_steps
    monkeypatch.setattr(config.Output, "total_steps",
                        property(lambda self: min(real.fget(self), MAX_STEPS)))


def test_the_unmutated_base_runs():
    with tempfile.TemporaryDirectory() as d:
        code, err, *_ = run_cli(BASE, d)
    assert code == 0, err


@settings(max_examples=int(os.environ.get("KAPSEL_FUZZ_EXAMPLES", 60)), deadline=None,
          derandomize=os.environ.get("KAPSEL_FUZZ_RANDOM") is None, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(mutated())
def test_mutated_input_runs_or_is_refused_cleanly(case):
    text, edits = case
    with tempfile.TemporaryDirectory() as d:
        try:
            code, err, out, before, after, caught = run_cli(text, d)
        except TooSlow:
            raise
        except BaseException:
            pytest.fail(f"edits {edits}: kapsel-py raised\n{traceback.format_exc()}")
    lines = err.strip().splitlines()
    what = f"edits {edits} -> exit {code}, stderr {err!r}"
    assert "Traceback" not in err, what
    if code == 0:
        return
    assert code in (cli.EXIT_BAD_INPUT, cli.EXIT_RUN_FAILED), what
    assert lines and all(line.startswith("kapsel-py: error: ") for line in lines), what
    assert len(set(lines)) == len(lines), what      # one line per problem, none repeated
    assert out == "", what
    if code == cli.EXIT_RUN_FAILED:
        assert len(lines) == 1, what
    if code == cli.EXIT_BAD_INPUT:
        assert after == before, f"{what}; written: {sorted(set(after) - set(before))}"
        assert not caught, f"{what}; warnings: {[str(w.message) for w in caught]}"
    else:
        assert "the run stopped at step" in lines[0] or "initial state" in lines[0], what
