"""kapsel-py: the extended KAPSEL simulator (kapsel_u2m) in Python.

``kapsel.Simulation`` drives a run from Python (kapsel.api); ``kapsel-py`` is the command.
"""
__version__ = "0.1.0"

_API = ("Simulation", "Particles", "BadInput", "RunError", "Interrupted", "NothingToDo",
        "Activity", "Every")


def __getattr__(name):
    """The run API (kapsel.api), imported on first use: ``import kapsel`` stays light and
    the command line sets its thread variables before numpy is imported."""
    if name in _API:
        from . import api
        return getattr(api, name)
    raise AttributeError(f"module 'kapsel' has no attribute {name!r}")
