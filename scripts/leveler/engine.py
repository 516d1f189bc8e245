"""The C engine's one Python binding: libleveler_diag.so (host_sim/diagnose/),
found once, its ABI checked once. The config loader's resolved config comes
from here (diag_config_json: the C loader's own JSON, docs/config-format.md),
not from a leveler-sim subprocess; the diagnosis's simulations go through the
same library (leveler.diagnose.cplant).

The library is looked up in $LEVELER_DIAG_LIB, then in the installed package
(pip install .: leveler/_lib), then in the build folders (leveler.paths)."""
import ctypes
import functools
import json

from . import paths

ABI = 5     # diag_abi_version() of host_sim/diagnose/diag_shim.c


class EngineError(RuntimeError):
    """The library is missing, of another ABI, or refused a request (its message)."""


def find_library(env="LEVELER_DIAG_LIB", folder="diagnose", name="libleveler_diag.so", target="leveler_diag"):
    try:
        return paths.compiled(env, f"_lib/{name}", f"host_sim/{folder}/{name}",
                              f"build it with `cmake --build build/sim --target {target}`")
    except paths.NotFound as e:
        raise EngineError(str(e)) from None


@functools.lru_cache(maxsize=None)
def load(path):
    """A C library by path, loaded once per process."""
    return ctypes.CDLL(path)


@functools.lru_cache(maxsize=None)
def library(path=None):
    """libleveler_diag.so, refused when built for another ABI (rebuild it)."""
    lib = load(path or find_library())
    if lib.diag_abi_version() != ABI:
        raise EngineError(f"libleveler_diag.so has ABI {lib.diag_abi_version()}, this code needs {ABI}: rebuild it")
    lib.diag_config_json.restype = ctypes.c_int
    lib.diag_config_json.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_int]
    return lib


def config_json(path=None):
    """The resolved config (SI; the built-in thesis 900 lb one for None) as the C
    loader reads it, as a dict; EngineError with the loader's file:line message."""
    lib = library()
    err = ctypes.create_string_buffer(1024)
    arg = None if path is None else str(path).encode()
    need = lib.diag_config_json(arg, None, 0, err, len(err))
    if need < 0:
        raise EngineError(err.value.decode(errors="replace"))
    buf = ctypes.create_string_buffer(need + 1)
    if lib.diag_config_json(arg, buf, len(buf), err, len(err)) < 0:
        raise EngineError(err.value.decode(errors="replace"))
    return json.loads(buf.value.decode())
