"""The thesis 900 lb scenario through leveler-rig (unchanged, closed loop over
real Modbus TCP against leveler-plant-server in lockstep) must give the same
event figures as leveler-sim on the same plant config, within the plant
issue's tolerances: heights 0.05 in, pressures 2 psi, times stuck 2.5 s.

    rig_vs_sim.py LEVELER_RIG PLANT_SERVER LEVELER_SIM CONFIG.ini OUT_DIR

Event figures come from `python -m leveler.report --log X --summary Y.json`
(scripts/leveler, on PYTHONPATH). Prints both sets side by side and writes
OUT_DIR/rig-vs-sim.json. Exit 0 when every figure agrees, 1 otherwise.
"""
import json
import os
import subprocess
import sys
import tempfile
import time

IN_M = 0.0254
PSI_PA = 6894.757293168361
TOLERANCES = {  # by unit suffix of the summary key
    "_m": (0.05 * IN_M, IN_M, "in"),
    "_pa": (2.0 * PSI_PA, PSI_PA, "psi"),
    "_s": (2.5, 1.0, "s"),
}

RIG_INI = """[rig]
name = {name}
clock = lockstep
run_seconds = {end_s}
[sensors]
transport = tcp
host = 127.0.0.1
port = {port}
timeout_ms = 2000
[sensor.height]
register = 0
[sensor.p_spring]
register = 1
[sensor.p_pipe]
register = 2
[sensor.p_acc]
register = 3
[sensor.load]
register = 4
raw_lo = 0
raw_hi = 1
load_n_lo = 0
load_n_hi = 1
[outputs]
backend = modbus
[output.compressor]
coil = 0
[output.spring_valve]
coil = 1
[output.vent_valve]
coil = 2
[output.acc_valve]
coil = 3
[supervision]
enabled = false
[log]
path = {log}
"""


def wait_for_port(path, proc, timeout_s=20.0):
    until = time.monotonic() + timeout_s
    while time.monotonic() < until:
        if proc.poll() is not None:
            raise SystemExit(f"leveler-plant-server exited with {proc.returncode} before listening")
        try:
            with open(path) as f:
                text = f.read().strip()
            if text:
                return int(text)
        except FileNotFoundError:
            pass
        time.sleep(0.01)
    raise SystemExit(f"{path}: no port after {timeout_s} s")


def summary(log, out_json):
    subprocess.run([sys.executable, "-m", "leveler.report", "--log", log, "--summary", out_json],
                   check=True, timeout=120, stdout=subprocess.DEVNULL)
    with open(out_json) as f:
        return json.load(f)


def main():
    rig, plant_server, sim, config, out_dir = sys.argv[1:6]
    os.makedirs(out_dir, exist_ok=True)
    work = tempfile.mkdtemp(prefix="leveler-rig-vs-sim-", dir=out_dir)
    port_file = os.path.join(work, "plant.port")
    rig_log = os.path.join(work, "rig.csv")
    sim_log = os.path.join(work, "sim.csv")
    end_s = 55

    with open(os.path.join(work, "plant.out"), "w") as plant_out:
        plant = subprocess.Popen([plant_server, "--config", config, "--port", "0", "--port-file", port_file,
                                  "--clock", "lockstep", "--max-seconds", "300"],
                                 stdout=plant_out, stderr=subprocess.STDOUT)
        try:
            port = wait_for_port(port_file, plant)
            rig_ini = os.path.join(work, "rig.ini")
            with open(rig_ini, "w") as f:
                f.write(RIG_INI.format(name="thesis-900lb", end_s=end_s, port=port, log=rig_log))
            t0 = time.monotonic()
            subprocess.run([rig, "--config", rig_ini], check=True, timeout=240)
            rig_wall = time.monotonic() - t0
        finally:
            plant.terminate()
            plant.wait(timeout=10)

    t0 = time.monotonic()
    subprocess.run([sim, "--config", config, "--log", sim_log, "--end-s", str(end_s)], check=True, timeout=240)
    sim_wall = time.monotonic() - t0

    rig_fig = summary(rig_log, os.path.join(work, "rig.json"))
    sim_fig = summary(sim_log, os.path.join(work, "sim.json"))

    failures = []
    rows = []
    print(f"{'figure':30s} {'unit':>4s} {'leveler-rig':>12s} {'leveler-sim':>12s} {'diff':>8s} {'tol':>6s}")
    for key, sim_v in sim_fig.items():
        rig_v = rig_fig.get(key)
        suffix = next(s for s in TOLERANCES if key.endswith(s))
        tol, scale, unit = TOLERANCES[suffix]
        if sim_v is None or rig_v is None:
            ok = sim_v is None and rig_v is None
            diff = None
        else:
            diff = rig_v - sim_v
            ok = abs(diff) <= tol
        if key.startswith("time_return"):
            ok = True  # not one of the compared figures (no tolerance given); shown only
        fmt = (lambda v: "-" if v is None else f"{v / scale:.3f}")
        print(f"{key:30s} {unit:>4s} {fmt(rig_v):>12s} {fmt(sim_v):>12s} {fmt(diff):>8s} {tol / scale:6.2f}"
              f"{'' if ok else '  <-- outside tolerance'}")
        rows.append({"figure": key, "rig": rig_v, "sim": sim_v, "difference": diff, "tolerance": tol, "ok": ok})
        if not ok:
            failures.append(key)
    print(f"wall time: leveler-rig lockstep {rig_wall:.2f} s, leveler-sim {sim_wall:.2f} s (55 s simulated)")
    with open(os.path.join(out_dir, "rig-vs-sim.json"), "w") as f:
        json.dump({"figures": rows, "rig_wall_s": rig_wall, "sim_wall_s": sim_wall}, f, indent=1)
    if failures:
        print("outside tolerance: " + ", ".join(failures) + f" (logs kept in {work})")
        return 1
    for name in os.listdir(work):
        os.remove(os.path.join(work, name))
    os.rmdir(work)
    return 0


if __name__ == "__main__":
    sys.exit(main())
