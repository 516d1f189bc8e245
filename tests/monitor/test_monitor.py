"""Issue 22: leveler-monitor's page in a real headless browser (Chromium over
the DevTools protocol) against a real rig: leveler-plant-server (the thesis
900 lb plant, load step at 5 s) + leveler-rig, the monitor on the rig's Modbus
TCP port.

Read-only: the page loads, its trends move (the displayed time and height
change as the plant runs, the trend's points grow) and it offers no writes.
With --allow-writes: band, mode and a commissioning setting written through
the page's own controls arrive in the firmware (read back over Modbus with
pymodbus, an independent peer); a band the firmware refuses shows the
firmware's reason on the page and changes nothing; the UPlimit line algorithm 3
learns is drawn where the firmware has it. Over Modbus RTU: the firmware as a
board behind a pseudo-terminal (monitor_pty_board), its height shown as its
calibration gives it, a stall fault named, writes read back inside the firmware.
Screenshots of the pages are kept (LEVELER_MONITOR_ARTEFACTS, printed).
"""
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "rig" / "py"))
sys.path.insert(0, str(Path(__file__).parent))
import cdp  # noqa: E402
import rigproc  # noqa: E402

REGS = {r["name"]: r for r in json.loads((ROOT / "firmware/regmap/registers.json").read_text())["registers"]}
MONITOR = ROOT / "scripts" / "leveler-monitor"
ARTEFACTS = Path(os.environ.get("LEVELER_MONITOR_ARTEFACTS", "."))
NOW_JS = "textDeep('lm-now') || ''"


def holding(client, name):
    """A holding register read over Modbus with pymodbus, decoded here from registers.json (hi word first)."""
    r = REGS[name]
    words = 2 if r["type"] in ("int32", "uint32") else 1
    rr = client.read_holding_registers(r["address"], count=words)
    assert not rr.isError(), rr
    v = rr.registers[0] if words == 1 else rigproc.u32(rr.registers)
    return v - (1 << 32) if r["type"] == "int32" and v >= 1 << 31 else v


class Monitor:
    def __init__(self, tmp, rig_port, *extra):
        port_file = tmp / "http.port"
        port_file.unlink(missing_ok=True)
        self.out_path = tmp / "monitor.out"
        self.out = open(self.out_path, "a")
        self.proc = subprocess.Popen([str(MONITOR), "--host", "127.0.0.1", "--port", str(rig_port), "--http-port", "0",
                                      "--http-port-file", str(port_file), *extra], stdout=self.out,
                                     stderr=subprocess.STDOUT)
        self.url = f"http://127.0.0.1:{rigproc.read_port(port_file, self.proc, 30, self.out_path)}/"

    def stop(self):
        """SIGTERM: the page's server stops, exit 0."""
        self.proc.send_signal(signal.SIGTERM)
        rc = self.proc.wait(15)
        self.out.close()
        return rc


@pytest.fixture
def browser(tmp_path):
    chromium = cdp.find_chromium()
    if chromium is None:
        pytest.skip("no chromium")
    b = cdp.Browser(chromium, tmp_path / "profile")
    yield b
    b.close()


# rigproc's 5 ms sensor timeout fails scans (and latches sensor faults) when Chromium and
# the other tests load the machine; these tests are about the page, not the link.
SENSORS_SLACK = {"sensors": {"timeout_ms": 50}}


@pytest.fixture
def rig(tmp_path):
    plant = rigproc.Plant(tmp_path, config=rigproc.PLANT_CONFIG)
    r = rigproc.Rig(tmp_path, plant, overrides=SENSORS_SLACK).start()
    yield r
    r.stop()
    plant.stop()


def shown(text):
    """(t, height mm) of the page's readout line."""
    m = re.search(r"t = ([0-9.]+) s\s+height ([0-9.]+) mm", text)
    assert m, text
    return float(m.group(1)), float(m.group(2))


def open_page(browser, url):
    """The page open and showing a reading. A browser lost on the way (its DevTools
    connection closed: nothing the page can do) is reported and replaced once."""
    def reading():
        browser.open(url)
        return browser.wait_js(f"/height/.test({NOW_JS})", 30)
    try:
        ok = reading()
    except cdp.BrowserLost as lost:
        print(f"open_page: {lost}\nopen_page: a new browser, once", file=sys.stderr)
        browser.restart()
        ok = reading()
    assert ok, "the page never showed a reading"


def test_read_only_page_trends_move(tmp_path, rig, browser):
    mon = Monitor(tmp_path, rig.port)
    try:
        open_page(browser, mon.url)
        t1, h1 = shown(browser.js(NOW_JS))
        n1 = browser.js("Bokeh.documents[0].get_model_by_name('trend').data.t.length")
        heights = {h1}
        until = time.monotonic() + 20
        while len(heights) < 3 and time.monotonic() < until:
            time.sleep(0.5)
            t2, h2 = shown(browser.js(NOW_JS))
            heights.add(h2)
        n2 = browser.js("Bokeh.documents[0].get_model_by_name('trend').data.t.length")
        assert t2 > t1 and n2 > n1, (t1, t2, n1, n2)
        assert len(heights) >= 3, f"the displayed height did not move as the plant ran: {heights}"
        with rig.client() as c:
            lo, hi = holding(c, "band_lower_um") / 1000, holding(c, "band_upper_um") / 1000
        assert lo - 60 < h2 < hi + 60, (h2, lo, hi)      # a height of this rig (within its travel)
        assert browser.js("findDeep('lm-band-set') === null && findDeep('lm-result') === null"), \
            "a read-only page offers writes"
        print("monitor screenshot (read-only):", browser.screenshot(ARTEFACTS / "monitor-read-only.png"))
        rig.stop()                                          # the rig goes away: the page says so, the monitor lives on
        assert browser.wait_js(f"/link:/.test({NOW_JS})", 15), browser.js(NOW_JS)
    finally:
        assert mon.stop() == 0, mon.out_path.read_text()


def set_input(browser, cls, value):
    """Types value into the page's text input (or select) cls as a user would, then the change event."""
    assert browser.js(f"""(() => {{ const el = inner('{cls}', 'input, select'); if (!el) return false;
        el.focus(); el.value = {json.dumps(value)}; el.dispatchEvent(new Event('input', {{bubbles: true}}));
        el.dispatchEvent(new Event('change', {{bubbles: true}})); return true; }})()"""), cls


def click(browser, cls):
    assert browser.js(f"(() => {{ const b = inner('{cls}', 'button'); if (!b) return false; b.click(); return true; }})()"), cls


def result_after(browser, cls):
    """Clicks cls's button and returns the write's result line once it changed."""
    before = browser.js("(textDeep('lm-result') || '')")
    click(browser, cls)
    return browser.wait_js(f"(() => {{ const t = textDeep('lm-result') || '';"
                           f" return t !== {json.dumps(before)} ? t : ''; }})()", 10)


def commission(browser, c, name, text, expect):
    """Commissioning through the page: pick the setting, wait for its current value
    (read over Modbus) to show, type the new one, write, read it back over Modbus."""
    set_input(browser, "lm-setting", name)
    now = holding(c, name)
    enum = {v: k for k, v in REGS[name].get("enum", {}).items()}
    assert browser.wait_js(f"(inner('lm-setting-value', 'input') || {{}}).value === {json.dumps(enum.get(now, str(now)))}",
                           5), f"{name}: the page did not show its current value {now}"
    set_input(browser, "lm-setting-value", text)
    assert "written" in result_after(browser, "lm-setting-set")
    assert holding(c, name) == expect


def band_writes(browser, c):
    set_input(browser, "lm-band-lower", "395.000")
    set_input(browser, "lm-band-upper", "402.500")
    assert "written" in result_after(browser, "lm-band-set")
    assert (holding(c, "band_lower_um"), holding(c, "band_upper_um")) == (395000, 402500)
    assert browser.wait_js("/band_lower_um\\s+395000\\s/.test(textDeep('lm-settings') || '')", 5), \
        "the page's settings never showed the written band"
    set_input(browser, "lm-band-lower", "403.000")          # above the upper edge: refused
    text = result_after(browser, "lm-band-set")
    assert "refused" in text and "band_order" in text, text
    assert (holding(c, "band_lower_um"), holding(c, "band_upper_um")) == (395000, 402500)
    rr = c.read_input_registers(REGS["last_refusal_reason"]["address"], count=1)
    assert rr.registers[0] == REGS["last_refusal_reason"]["enum"]["band_order"]


def mode_write(browser, c, mode):
    set_input(browser, "lm-mode", mode)
    assert "written" in result_after(browser, "lm-mode-set")
    assert holding(c, "mode") == REGS["mode"]["enum"][mode]
    assert browser.wait_js(f"/mode\\s+{mode}/.test(textDeep('lm-status') || '')", 5)


def learnt_up_line(browser, c):
    """Algorithm 3 learns the UPlimit line in the climb after the load step; the page's
    line must pass through the learnt pressure at the target height with the learnt slope."""
    up = rigproc.wait_until(lambda: holding(c, "alg3_up_pa"), 40, 0.5)
    if not up:
        rr = c.read_input_registers(REGS["latched_fault_bits"]["address"], count=1)
        pytest.fail(f"algorithm 3 learnt no UPlimit line in 40 s (latched fault bits {rr.registers})")
    lo, hi = holding(c, "band_lower_um"), holding(c, "band_upper_um")
    target_mm = (lo + holding(c, "alg3_target_permille") * (hi - lo) / 1000) / 1000
    slope_kpa_per_mm = holding(c, "alg3_line_slope_pa_per_mm") / 1000
    line_js = "Bokeh.documents[0].get_model_by_name('up_line').data"

    def matches():
        d = browser.js(f"(() => {{ const d = {line_js}; return {{x: Array.from(d.x), y: Array.from(d.y)}}; }})()")
        if len(d["x"]) != 2:
            return False
        slope = (d["y"][1] - d["y"][0]) / (d["x"][1] - d["x"][0])
        at_target = d["y"][0] + slope * (target_mm - d["x"][0])
        return abs(slope - slope_kpa_per_mm) < 1e-6 and abs(at_target - holding(c, "alg3_up_pa") / 1000) < 0.01
    assert rigproc.wait_until(matches, 5, 0.2), f"the page's UPlimit line is not the learnt one ({up} Pa)"


def test_writes_round_trip(tmp_path, rig, browser):
    mon = Monitor(tmp_path, rig.port, "--allow-writes")
    try:
        open_page(browser, mon.url)
        assert browser.wait_js("(inner('lm-band-lower', 'input') || {}).value", 20), "band inputs never filled"
        with rig.client() as c:
            commission(browser, c, "algorithm", "hysteresis_aware", REGS["algorithm"]["enum"]["hysteresis_aware"])
            band_writes(browser, c)
            mode_write(browser, c, "off")
            mode_write(browser, c, "auto")
            commission(browser, c, "alg3_target_permille", "450", 450)
            learnt_up_line(browser, c)
        print("monitor screenshot (writes, learnt line):", browser.screenshot(ARTEFACTS / "monitor-writes.png"))
    finally:
        assert mon.stop() == 0, mon.out_path.read_text()


def test_read_only_rig_refuses_the_pages_writes(tmp_path, browser):
    """A rig whose supervision is read_only answers every write with exception 01:
    the page says so and nothing changes."""
    plant = rigproc.Plant(tmp_path)
    r = rigproc.Rig(tmp_path, plant, overrides={"supervision": {"read_only": "true"}, **SENSORS_SLACK}).start()
    mon = None
    try:
        mon = Monitor(tmp_path, r.port, "--allow-writes")
        open_page(browser, mon.url)
        assert browser.wait_js("(inner('lm-band-lower', 'input') || {}).value", 20), "band inputs never filled"
        set_input(browser, "lm-mode", "off")
        text = result_after(browser, "lm-mode-set")
        assert "not written" in text and "exception 01" in text, text
        with r.client() as c:
            assert holding(c, "mode") == REGS["mode"]["enum"]["auto"]
    finally:
        if mon is not None:
            assert mon.stop() == 0, mon.out_path.read_text()
        r.stop()
        plant.stop()


def calibrated_mm(channel, counts):
    """A reading at counts through the default two-point calibration of registers.json (mm or kPa)."""
    d = {k: REGS[f"cal_{channel}_{k}"]["default"] for k in ("raw_lo", "raw_hi", "eng_lo", "eng_hi")}
    return (d["eng_lo"] + (counts - d["raw_lo"]) * (d["eng_hi"] - d["eng_lo"]) / (d["raw_hi"] - d["raw_lo"])) / 1000


def test_board_over_rtu(tmp_path, browser):
    """The firmware as a board on a pseudo-terminal (monitor_pty_board: ADC counts fixed at
    2048/1500/1600/1700, tests/modbus/hal_pty.c), leveler-monitor over Modbus RTU. A pty
    carries no parity bits (Linux refuses PARENB on one): 8N1 here, 8E1 on a board's line."""
    board_bin = os.environ.get("LEVELER_PTY_BOARD")
    if not board_bin:
        pytest.skip("monitor_pty_board not built")
    board = subprocess.Popen([board_bin], stdout=subprocess.PIPE, text=True)
    mon = None
    try:
        pty = board.stdout.readline().split()[1]
        mon = Monitor(tmp_path, 1, "--serial", pty, "--parity", "N", "--allow-writes")
        open_page(browser, mon.url)
        assert abs(shown(browser.js(NOW_JS))[1] - calibrated_mm("height", 2048)) < 0.01
        assert browser.wait_js("(inner('lm-setting-value', 'input') || {}).value", 20), "setting input never filled"
        set_input(browser, "lm-setting", "stall_window_s")          # a stall within 1 s: the height never rises
        assert browser.wait_js(f"(inner('lm-setting-value', 'input') || {{}}).value === "
                               f"'{REGS['stall_window_s']['default']}'", 5)
        set_input(browser, "lm-setting-value", "1")
        assert "written" in result_after(browser, "lm-setting-set")
        assert browser.wait_js("/latched faults\\s+stall/.test(textDeep('lm-status') || '')", 10), \
            "the page never named the stall fault"
        set_input(browser, "lm-band-lower", "395.000")
        set_input(browser, "lm-band-upper", "402.500")
        assert "written" in result_after(browser, "lm-band-set")
        set_input(browser, "lm-mode", "off")
        assert "written" in result_after(browser, "lm-mode-set")
        assert "written" in result_after(browser, "lm-clear-set")      # off: no fill, so no new stall
        assert browser.wait_js("/latched faults\\s+none/.test(textDeep('lm-status') || '')", 5), \
            "the page still shows a latched fault after clear faults"
        print("monitor screenshot (RTU board):", browser.screenshot(ARTEFACTS / "monitor-rtu.png"))
    finally:
        if mon is not None:
            assert mon.stop() == 0, mon.out_path.read_text()
        board.send_signal(signal.SIGTERM)
        said = board.communicate(timeout=10)[0]
    # read inside the firmware after the monitor let go of the line
    assert f"mode {REGS['mode']['enum']['off']} band_lower_um 395000 band_upper_um 402500 latched_fault_bits 0" \
        in said, said


if __name__ == "__main__":
    # CTest (tests/monitor/CMakeLists.txt): 77 = skipped, only when no Chromium is installed.
    if cdp.find_chromium() is None:
        print(f"monitor_browser: skipped: none of {', '.join(cdp.CHROMIUM_NAMES)} installed (scripts/bootstrap)")
        sys.exit(77)
    sys.exit(pytest.main(["-q", "-s", "-p", "no:cacheprovider", __file__] + sys.argv[1:]))
