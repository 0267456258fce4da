"""Shared by the tests: the command's main() run in a directory."""
import os

from kapsel.cli import main


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
