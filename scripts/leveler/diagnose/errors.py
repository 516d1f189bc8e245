"""One exception type for every bad input, so the CLI prints it and exits 2."""


class DiagnoseInputError(Exception):
    """Bad input: the message names the file, line and field where possible."""


def where(path, line=None, field=None):
    """'path:line: field' prefix for error messages."""
    out = str(path)
    if line is not None:
        out += f":{line}"
    if field is not None:
        out += f": {field}"
    return out
