"""The command style every leveler program shares, on the Python side
(host_sim/cli/include/cli.h is the C side): argparse with --opt VALUE and
--opt=VALUE, --help (exit 0), --version, one help layout ending with the exit
codes, and files created with the user's umask.

Exit codes: 0 done, 1 the job failed, 2 bad input (argparse's own usage errors
are 2 as well).
"""
import argparse
import os

from . import __version__

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2
EXIT_CODES = "exit codes: 0 done, 1 the job failed, 2 bad input (an option, a config, a file)"


class _Parser(argparse.ArgumentParser):
    """argparse laid out as the C programs' help (host_sim/cli): the usage line,
    the options (--help and --version last), then the exit codes."""

    def __init__(self, *args, **kw):
        kw["add_help"] = False   # added last, by _add_common (sub-command parsers too)
        super().__init__(*args, **kw)

    def _add_common(self):
        if not getattr(self, "_common_added", False):
            self._common_added = True
            self.add_argument("-h", "--help", action="help", help="this help, exit 0")
            self.add_argument("--version", action="version", version=f"{self.prog} {__version__}",
                              help="print the program's version, exit 0")

    def parse_known_args(self, args=None, namespace=None):
        self._add_common()
        return super().parse_known_args(args, namespace)

    def format_help(self):
        self._add_common()
        return super().format_help()


def parser(prog, description, exit_extra=None):
    """An ArgumentParser with --help and --version and the exit codes under the options."""
    ap = _Parser(prog=prog, description=description,
                 epilog=EXIT_CODES + (f", {exit_extra}" if exit_extra else ""),
                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap._optionals.title = "options (--opt VALUE or --opt=VALUE)"
    return ap


def umask_mode(base):
    """``base`` (0o666 for files, 0o777 for folders) less the process's umask:
    the mode open() would give, for files made through mkstemp/mkdtemp (0600/0700)."""
    mask = os.umask(0)
    os.umask(mask)
    return base & ~mask
