#!/usr/bin/env python3
"""The walk of one diagnosis through the package's rooms (docs/architecture.md):
every function of the leveler package in the order it is first called, each
mapped to its room (its module), consecutive ones in the same room joined into
one stay. Prints the walk, the stays, the rooms and the returns (stays in a room
visited before): how often a reader following the code changes file.

  scripts/walk_rooms.py --config thesis-900lb --run a.csv --run b.csv --holdout c.csv

Takes the arguments of leveler-diagnose (--out and --jobs 1 are added: every
step in this process)."""
import os
import sys
import tempfile


def walk(argv):
    from leveler.diagnose import cli
    first, order = set(), []

    def profile(frame, event, arg):
        if event != "call":
            return
        code = frame.f_code
        mod = frame.f_globals.get("__name__", "")
        if not mod.startswith("leveler") or (code.co_filename, code.co_firstlineno) in first:
            return
        first.add((code.co_filename, code.co_firstlineno))
        order.append((mod, code.co_name))

    out = tempfile.mkdtemp(prefix="leveler-walk-")
    sys.setprofile(profile)
    try:
        cli.main(list(argv) + ["--out", os.path.join(out, "d"), "--jobs", "1", "--quiet"])
    finally:
        sys.setprofile(None)
    return order


def stays(order, skip=("leveler.cli", "leveler.diagnose.cli", "leveler.diagnose.__main__")):
    """Consecutive calls in one room joined: [(room, [functions])]."""
    out = []
    for mod, fn in order:
        if mod in skip:
            continue
        if out and out[-1][0] == mod:
            out[-1][1].append(fn)
        else:
            out.append((mod, [fn]))
    return out


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if "-h" in argv or "--help" in argv:
        print(__doc__)
        return 0
    if "--version" in argv:
        import leveler
        print(f"walk_rooms {leveler.__version__}")
        return 0
    s = stays(walk(argv))
    for room, fns in s:
        print(f"{room:40s} {', '.join(fns[:6])}{' ...' if len(fns) > 6 else ''}")
    rooms = {r for r, _ in s}
    print(f"stays {len(s)}, rooms {len(rooms)}, returns {len(s) - len(rooms)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
