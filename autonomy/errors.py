"""Errors that the command line reports as one clear line and exit code 2."""


class UserError(Exception):
    """Bad input from the user (a file, a flag, a value): shown without a traceback."""
