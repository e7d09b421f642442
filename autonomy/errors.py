"""Errors that the command line reports as one clear line and exit code 2."""


class UserError(Exception):
    """Bad input from the user (a file, a flag, a value): shown without a traceback."""


def one_line(text: str, limit: int = 300) -> str:
    """``text`` on one line (runs of white space, newlines included, made one space), cut to
    ``limit`` characters."""
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."
