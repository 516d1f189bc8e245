"""One exception type for every bad input, so the CLI prints it and exits 2."""


class DiagnoseInputError(Exception):
    """Bad input: the message names the file, line and field where possible."""

