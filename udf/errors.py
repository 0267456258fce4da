"""One exception for everything that can be wrong with a UDF file or a UDF path."""
from __future__ import annotations


class UDFError(Exception):
    """A problem in a UDF file (with file, line and column) or with a UDF path.

    str(err) is a single line meant for the user, e.g.
    ``input.udf:12:5: expected a number for mesh.NPX, found "five"``.
    """

    def __init__(self, message: str, file: str | None = None, line: int | None = None,
                 column: int | None = None, path: str | None = None):
        self.message = message
        self.file = file
        self.line = line
        self.column = column
        self.path = path
        super().__init__(self.format())

    def format(self) -> str:
        where = ""
        if self.file:
            where = str(self.file)
            if self.line is not None:
                where += f":{self.line}"
                if self.column is not None:
                    where += f":{self.column}"
            where += ": "
        return where + self.message


class UDFErrors(UDFError):
    """Several problems of one file, reported together: str() is one line per problem."""

    def __init__(self, errors: list):
        self.errors = list(errors)
        first = self.errors[0]
        super().__init__(first.message, first.file, first.line, first.column, first.path)
        self.args = (self.format(),)

    def format(self) -> str:
        errors = getattr(self, "errors", None)
        if not errors:
            return super().format()
        return "\n".join(e.format() for e in errors)


def raise_all(errors: list) -> None:
    """Raise the one error, or all of them together; nothing if the list is empty."""
    if len(errors) == 1:
        raise errors[0]
    if errors:
        raise UDFErrors(errors)
