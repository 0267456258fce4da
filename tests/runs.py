"""Shared by the tests: the manual's sample as a starting input, and the command's main()
run in a directory."""
import os
import shutil

from kapsel.cli import main
from udf import UDFManager

SAMPLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "samples")


def sample_input(d, eq, npx=4):
    """The manual's sample in directory ``d`` (its define.udf and kapsel_unit.udf copied
    there) as a UDFManager, with constitutive_eq.type ``eq`` and 2^npx cells per side; the
    caller puts the rest and writes it."""
    os.makedirs(d, exist_ok=True)
    for f in ("define.udf", "kapsel_unit.udf"):
        shutil.copy(os.path.join(SAMPLES, f), os.path.join(d, f))
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put(eq, "constitutive_eq.type")
    for k in ("NPX", "NPY", "NPZ"):
        u.put(npx, f"mesh.{k}")
    return u


def continue_input(d, num_snap=4) -> str:
    """``d``/cont.udf: ``d``/restart.udf as the input of a continued run (output.Num_snap
    raised to ``num_snap``), with the restart's state file beside it; returns its path."""
    from kapsel.io.restart import state_path
    rs = UDFManager(os.path.join(d, "restart.udf"))
    rs.put(num_snap, "output.Num_snap")
    cont = os.path.join(d, "cont.udf")
    rs.write(cont)
    shutil.copy(state_path(os.path.join(d, "restart.udf")), state_path(cont))
    return cont


def run_cli(d, inp, *extra, seed):
    """kapsel-py -I<inp> -Ooutput.udf -Ddefine.udf -Rrestart.udf --seed <seed> --quiet
    <extra> run in directory ``d``; returns the exit code."""
    cwd = os.getcwd()
    os.chdir(d)
    try:
        return main([f"-I{inp}", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed",
                     str(seed), "--quiet", *extra])
    finally:
        os.chdir(cwd)
