"""Errors a user can act on. The CLI prints them as one line and exits with code 2."""


class RetimeError(Exception):
    """A problem with the user's input or request (not a bug in retime)."""


class FormatError(RetimeError):
    """A motion, warp or body file that cannot be read.

    The message names the file, the line (or frame) and what is wrong.
    """

    def __init__(self, path, message, line=None):
        self.path = str(path)
        self.line = line
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")
