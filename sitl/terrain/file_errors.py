"""The error of an elevation model file that is not what it should be."""


class GridFileError(ValueError):
    """A malformed or oversized elevation model: ``FILE:LINE: reason`` or ``FILE: reason``,
    in the project's words (the reader has named the file)."""
