"""Errors raised on bad input files."""


class RatingsFileError(ValueError):
    """A ratings file that cannot be used; the message names the file, line and problem."""
