"""One exception type for every bad input, across the package: the CLIs print
it and exit 2. The message names the file, line and field where possible."""


class InputError(Exception):
    """Bad input (a config, a log, a schedule): file:line: field: why."""
