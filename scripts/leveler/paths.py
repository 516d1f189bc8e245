"""Where the leveler package finds the project's files.

An installed package (pip install ., pyproject.toml) carries them inside
itself (cmake/python_package.cmake): ``_lib/`` the C libraries, ``_bin/``
leveler-sim, ``_data/`` the simulator configs, the effect and truth
catalogues and the register map. A checkout has them in its source tree and its build folders.

Compiled files: $ENV first, then the installed package, then the checkout's
build folders (newest first). Data files: the checkout's own, else the
installed package's copy.
"""
import glob
import os

PACKAGE = os.path.dirname(os.path.abspath(__file__))


def _checkout():
    """The checkout this package runs from (it is <root>/scripts/leveler), else None."""
    root = os.path.dirname(os.path.dirname(PACKAGE))
    here = os.path.join(root, "scripts", "leveler")
    if os.path.isfile(os.path.join(root, "VERSION")) and os.path.isdir(here) and os.path.samefile(here, PACKAGE):
        return root
    return None


ROOT = _checkout()
BUILD_DIRS = ("build/sim", "build/bench", "build/test", "build/*")


class NotFound(LookupError):
    """A compiled file is in none of the places looked at."""


def packaged(*parts):
    """A file installed inside the package, or None."""
    p = os.path.join(PACKAGE, *parts)
    return p if os.path.exists(p) else None


def in_build(rel, build_dirs=BUILD_DIRS, ok=os.path.isfile):
    """The newest usable ``build/<dir>/rel`` of the checkout, or None (also outside a checkout)."""
    if ROOT is None:
        return None
    cands = [c for b in build_dirs for c in glob.glob(os.path.join(ROOT, b, rel)) if ok(c)]
    return max(cands, key=os.path.getmtime) if cands else None


def compiled(env, packaged_rel, build_rel, hint, build_dirs=BUILD_DIRS, ok=os.path.isfile):
    """A compiled file: $env, else the installed package's, else the build folders'.
    ok: what makes a candidate usable (a file; for a program, an executable one)."""
    path = os.environ.get(env)
    if path:
        if not ok(path):
            raise NotFound(f"{env}={path}: " + ("not an executable" if os.path.isfile(path) else "no such file"))
        return path
    for path in (packaged(*packaged_rel.split("/")), in_build(build_rel, build_dirs, ok)):
        if path and ok(path):
            return path
    raise NotFound(f"{os.path.basename(build_rel)} not found: {hint}, set {env}, or pip install the package")


def data(checkout_rel, packaged_rel):
    """A data file or folder: the checkout's, else the installed package's copy
    (the checkout's path when neither exists, for the error message)."""
    if ROOT is not None:
        p = os.path.join(ROOT, *checkout_rel.split("/"))
        if os.path.exists(p):
            return p
    p = packaged("_data", *packaged_rel.split("/"))
    if p:
        return p
    return os.path.join(ROOT or PACKAGE, *checkout_rel.split("/"))
