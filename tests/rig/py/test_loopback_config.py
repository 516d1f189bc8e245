"""boards/linux-rig/rig-loopback.ini as a user runs it: leveler-plant-server on the
port the file names (--clock realtime, the thesis 900 lb plant), leveler-rig with
exactly that file, started in a folder of its own. A pymodbus client reads the
rig's height over its supervision port (the file's 1502) and the plant's own
height counts: the height lies inside the plant config's travel (its end stops,
as leveler-sim --dump-config gives them) and is the plant's, through the
firmware's calibration. Skipped when the file's ports are taken on this machine."""
import configparser
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest

import rigproc
from leveler import config as leveler_config

LOOPBACK = Path(__file__).resolve().parents[3] / "boards" / "linux-rig" / "rig-loopback.ini"
IR_HEIGHT_UM = 0
HR_CAL_HEIGHT = 32      # cal_height_raw_lo, raw_hi, eng_lo (int32), eng_hi (int32)


def port_taken(port):
    """Another server listens there (SO_REUSEADDR as the servers bind: a TIME_WAIT left by
    an earlier run does not count)."""
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return True
    return False


def i32(regs):
    v = rigproc.u32(regs)
    return v - (1 << 32) if v & 0x80000000 else v


def read_height_um(client):
    r = client.read_input_registers(IR_HEIGHT_UM, count=2)
    assert not r.isError(), r
    return i32(r.registers)


@pytest.fixture
def loopback(tmp_path):
    ini = configparser.ConfigParser()
    ini.read(LOOPBACK)
    module_port, rig_port = ini.getint("sensors", "port"), ini.getint("supervision", "port")
    assert ini.get("sensors", "host") == "127.0.0.1" and ini.get("outputs", "backend") == "modbus"
    for port in (module_port, rig_port):
        if port_taken(port):
            pytest.skip(f"127.0.0.1:{port} (named in {LOOPBACK.name}) is in use on this machine")
    plant = rigproc.Plant(tmp_path, config=rigproc.PLANT_CONFIG, clock="realtime", port=module_port)
    out = open(tmp_path / "rig.out", "w")
    work = tmp_path / "work"
    work.mkdir()
    proc = subprocess.Popen([rigproc.RIG, "--config", str(LOOPBACK)], cwd=work, stdout=out,
                                    stderr=subprocess.STDOUT)
    try:
        client = rigproc.wait_until(lambda: proc.poll() is None and _try_connect(rig_port), 10.0, 0.05)
        assert client, f"leveler-rig not serving 127.0.0.1:{rig_port}: {(tmp_path / 'rig.out').read_text()}"
        yield plant, proc, client, work
        client.close()
    finally:
        rigproc.stop_process(proc)
        out.close()
        plant.stop()


def _try_connect(port):
    try:
        return rigproc.connect(port)
    except RuntimeError:
        return None


def test_loopback_rig_reads_the_plants_height(loopback):
    plant, proc, rig, work = loopback
    lo_m, hi_m = (leveler_config.load(rigproc.PLANT_CONFIG).value("platform", k) for k in ("height_min_m", "height_max_m"))
    assert rigproc.wait_until(lambda: rig.read_discrete_inputs(rigproc.DI_SENSORS_VALID, count=1).bits[0], 5.0)
    cal = rig.read_holding_registers(HR_CAL_HEIGHT, count=6).registers
    raw_lo, raw_hi, eng_lo, eng_hi = cal[0], cal[1], i32(cal[2:4]), i32(cal[4:6])
    module = plant.client()
    try:
        for _ in range(5):
            h_um = read_height_um(rig)
            counts = module.read_input_registers(0, count=1).registers[0]
            plant_um = eng_lo + (counts - raw_lo) * (eng_hi - eng_lo) / (raw_hi - raw_lo)
            assert lo_m * 1e6 <= h_um <= hi_m * 1e6, (h_um, lo_m, hi_m)
            assert abs(h_um - plant_um) < 2000, (h_um, counts, plant_um)   # the plant's height, within 2 mm
            time.sleep(0.2)
    finally:
        module.close()
    state = rig.read_input_registers(rigproc.IR_CONTROL_STATE, count=1).registers[0]
    assert state != rigproc.STATE_SAFE and proc.poll() is None
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(10) == 0
    log = work / "leveler-loopback.csv"     # [log] path, relative to the folder the rig started in
    lines = log.read_text().splitlines()
    assert "# config: thesis-900lb" in lines and len([l for l in lines if not l.startswith("#")]) > 50
