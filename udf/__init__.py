"""The OCTA UDF language: grammar, schema, typed reader, writer and a UDFManager-compatible
API.  Knows nothing of physics."""
from .errors import UDFError
from .manager import UDFManager, atomic_write_text

__all__ = ["UDFError", "UDFManager", "atomic_write_text", "load"]


def load(path: str) -> UDFManager:
    """Read a UDF file (with its includes) into a UDFManager."""
    return UDFManager(path)
