"""bench-diagnose: wall time of one full diagnosis (2 calibration runs, 1 holdout,
all seven candidates in parallel processes) on blind-test logs. Prints figures
beside the targets on a 2-core machine: 30 s (issue 21), 10 s (issue 20)."""
import os
import subprocess
import sys
import tempfile
import time

from leveler import cli as leveler_cli
from leveler import engine

from . import blindtest
from .model import make_simulator


def main(argv=None):
    ap = leveler_cli.parser("bench-diagnose", __doc__)
    ap.add_argument("--out", default=None, help="folder for the logs and the diagnosis")
    ap.add_argument("--effect", default="thermal", choices=blindtest.CASES)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    top = a.out or tempfile.mkdtemp(prefix="leveler-bench-diagnose-")
    logs = os.path.join(top, "logs")
    os.makedirs(logs, exist_ok=True)
    sim = make_simulator()
    t0 = time.perf_counter()
    sim.generate(blindtest.CONFIG, *_thesis_grid(), None, [])
    one_sim = time.perf_counter() - t0
    blindtest.generate_case(sim, a.effect, 1, logs)
    times = []
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        cmd = [sys.executable, "-m", "leveler.diagnose", "--config", blindtest.CONFIG,
               "--run", os.path.join(logs, "cal1.csv"), "--run", os.path.join(logs, "cal2.csv"),
               "--holdout", os.path.join(logs, "hold.csv"), "--out", os.path.join(top, "diagnosis"), "--quiet"]
        subprocess.run(cmd, check=True)
        times.append(time.perf_counter() - t0)
    print(f"cores: {os.cpu_count()}")
    print(f"one 55 s closed-loop simulation (firmware in the loop): {one_sim * 1e3:.1f} ms")
    print(f"full diagnosis, 2 calibration + 1 holdout runs, 7 candidates: "
          f"best {min(times):.1f} s, median {sorted(times)[len(times) // 2]:.1f} s over {len(times)} "
          f"(targets: 30 s, issue 21; 10 s, issue 20)")
    return 0


def _thesis_grid():
    t = engine.tick_grid(55.0)
    lb = blindtest.LB
    load = engine.scenario_loads(t, {"base_load_n": 900 * lb, "step_load_n": 200 * lb,
                                    "step_on_s": 5.0, "step_off_s": 35.0, "end_s": 55.0})
    return t, load


if __name__ == "__main__":
    sys.exit(main())
