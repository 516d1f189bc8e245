"""The diagnosis's bad inputs: the package's one InputError (leveler.errors),
so a config or schedule the engine refuses is reported as any other."""
from leveler.errors import InputError as DiagnoseInputError

__all__ = ["DiagnoseInputError"]
