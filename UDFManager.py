"""OCTA's Python UDFManager, as users' scripts import it: ``from UDFManager import *``.

Installed with kapsel-py as a top-level module; the implementation is ``udf.octa``."""
from udf.octa import Location, UDFManager, rlocation

__all__ = ["UDFManager", "Location", "rlocation"]
