"""wmr-cosim: FMI co-simulation kit for H-infinity control of a wheeled mobile robot.

Sub-packages (each mapped from a top-level folder of the repository):
    wmr_cosim.components   the paper's models in plain Python (components/)
    wmr_cosim.fmus         the FMU slaves and their build (fmus/)
    wmr_cosim.cosim        the generic FMI master (cosim/)
    wmr_cosim.scenarios    the shipped scenario files, package data only (scenarios/)

The Python API (docs/scripting.md): ``from wmr_cosim import Simulation`` (also Run, Result, RunStatus,
ScenarioError, RunError), imported on first use so that ``import wmr_cosim`` stays light.
"""
__version__ = "0.1.0"  # the fallback when the distribution's metadata is not installed


def version() -> str:
    """The installed distribution's version (its metadata), else :data:`__version__`."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as _version

    try:
        return _version("wmr-cosim")
    except PackageNotFoundError:
        return __version__


_API = ("Simulation", "Run", "Result", "RunStatus", "ScenarioError", "RunError", "CosimError")


def __getattr__(name: str):
    if name in _API:
        from . import api
        return getattr(api, name)
    raise AttributeError(f"module 'wmr_cosim' has no attribute {name!r}")
