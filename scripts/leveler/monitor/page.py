"""leveler-monitor's page (one Bokeh document per browser tab): trends of
height with the band, P1/P2/P3 and the actuators; P2 against height with the
learnt hysteresis lines (the thesis's figure 20); the controller's state,
faults by name and the settings; the write controls with --allow-writes
(controls.py). Fed from the poller's ring of samples (modbus.py).

Shown units: heights in mm, pressures in kPa absolute (the map's um and Pa).
"""
import html

from bokeh.layouts import column, row
from bokeh.models import ColumnDataSource, Div
from bokeh.plotting import figure

from . import controls

TREND_COLUMNS = ("t", "h", "lo", "hi", "p1", "p2", "p3", "comp", "spring", "vent", "acc")
ACTUATORS = (("compressor_on", "comp", "compressor"), ("spring_valve_open", "spring", "spring valve"),
             ("vent_valve_open", "vent", "vent valve"), ("acc_valve_open", "acc", "accumulator valve"))
LINE_HALF_SPAN_MM = 50.8     # the hysteresis lines are drawn 2 in either side of the target
UNIT_SHOWN = {"um": (1e-3, "mm"), "Pa": (1e-3, "kPa")}
LEARNT_SHADE = " style='background:#fff3d6'"
PAGE_HZ = 2.0                # the page redraws at most this often (Page: what a redraw costs)


def shown(regmap, name, value):
    """value of name in the page's unit."""
    return value * UNIT_SHOWN.get(regmap[name]["unit"], (1, ""))[0]


def trend_row(regmap, t, v):
    row_ = {"t": t, "h": shown(regmap, "height_um", v["height_um"]),
            "lo": shown(regmap, "band_lower_um", v["band_lower_um"]),
            "hi": shown(regmap, "band_upper_um", v["band_upper_um"]),
            "p1": shown(regmap, "p_pipe_pa", v["p_pipe_pa"]),
            "p2": shown(regmap, "p_spring_pa", v["p_spring_pa"]),
            "p3": shown(regmap, "p_acc_pa", v["p_acc_pa"])}
    for i, (name, col, _) in enumerate(ACTUATORS):
        row_[col] = 1.5 * i + 0.8 * v[name]
    return row_


def hysteresis_lines(regmap, v):
    """The learnt UPlimit and DPlimit lines, P2 (kPa) against height (mm): each
    through its learnt pressure at the target height along the line slope."""
    lo, hi = v["band_lower_um"], v["band_upper_um"]
    target_mm = shown(regmap, "band_lower_um", lo + v["alg3_target_permille"] * (hi - lo) / 1000)
    slope = v["alg3_line_slope_pa_per_mm"]
    xs = [target_mm - LINE_HALF_SPAN_MM, target_mm + LINE_HALF_SPAN_MM]
    lines = {}
    for key, name in (("up", "alg3_up_pa"), ("down", "alg3_down_pa")):
        at = v[name]
        lines[key] = {"x": xs if at else [], "y": [(at + slope * (x - target_mm)) * 1e-3 for x in xs] if at else []}
    return lines


def trend_figures(src):
    height = figure(height=230, sizing_mode="stretch_width", title="height and band (mm)", x_axis_label="t (s)")
    height.line("t", "h", source=src, legend_label="height", line_width=2)
    for col in ("lo", "hi"):
        height.line("t", col, source=src, color="gray", line_dash="dashed", legend_label="band")
    press = figure(height=230, sizing_mode="stretch_width", title="pressures (kPa abs)", x_range=height.x_range,
                   x_axis_label="t (s)")
    for col, label, color in (("p1", "P1 pipe", "#1b9e77"), ("p2", "P2 spring", "#d95f02"),
                              ("p3", "P3 accumulator", "#7570b3")):
        press.line("t", col, source=src, legend_label=label, color=color, line_width=2)
    act = figure(height=170, sizing_mode="stretch_width", title="actuators (high = on / open)",
                 x_range=height.x_range, x_axis_label="t (s)")
    for i, (_, col, label) in enumerate(ACTUATORS):
        act.step("t", col, source=src, mode="after", legend_label=label, color=["#e7298a", "#66a61e", "#e6ab02",
                                                                                "#a6761d"][i])
    for fig in (height, press, act):
        fig.legend.click_policy = "hide"
        fig.add_layout(fig.legend[0], "right")
    act.yaxis.visible = False
    return [height, press, act]


def hysteresis_figure(trail, up, down):
    fig = figure(height=360, width=460, title="P2 against height (thesis fig. 20)",
                 x_axis_label="height (mm)", y_axis_label="P2 (kPa abs)")
    fig.scatter("h", "p2", source=trail, size=3, alpha=0.5, legend_label="P2 (recent)")
    fig.line("x", "y", source=up, color="firebrick", line_width=2, legend_label="UPlimit (learnt)")
    fig.line("x", "y", source=down, color="navy", line_width=2, legend_label="DPlimit (learnt)")
    fig.add_layout(fig.legend[0], "below")
    return fig


def set_text(div, text):
    """div's text, sent to the browser only when it changed (each change costs a layout)."""
    if div.text != text:
        div.text = text


class Page:
    """The document of one browser tab."""

    def __init__(self, doc, poller, regmap, link=None, rate_hz=10.0, window_s=120.0):
        self.doc, self.poller, self.regmap = doc, poller, regmap
        self.rollover = int(rate_hz * window_s)
        self.seq = 0
        self.last_settings = None
        self.trend = ColumnDataSource({c: [] for c in TREND_COLUMNS}, name="trend")
        self.trail = ColumnDataSource({"h": [], "p2": []}, name="trail")
        self.up = ColumnDataSource({"x": [], "y": []}, name="up_line")
        self.down = ColumnDataSource({"x": [], "y": []}, name="down_line")
        self.now = Div(text="waiting for the first reading", name="now", css_classes=["lm-now"])
        self.status = Div(text="", name="status", css_classes=["lm-status"], width=460)
        self.settings = Div(text="", name="settings", css_classes=["lm-settings"], sizing_mode="stretch_width")
        self.controls = controls.Controls(regmap, link) if link is not None else None
        doc.title = "leveler-monitor"
        doc.add_root(self.layout())
        # Every change to the document costs the browser a layout and a repaint of
        # every plot (about 30 ms of a core in headless Chromium, whatever changed):
        # at the poll rate the page took more than a core and starved a rig on the
        # same machine. The page redraws at PAGE_HZ, each time with every sample
        # polled since, and rewrites a text only when it changed.
        doc.add_periodic_callback(self.update, int(1000 / min(rate_hz, PAGE_HZ)))

    def layout(self):
        head = Div(text="<h2>leveler-monitor</h2>", sizing_mode="stretch_width")
        side = [self.status]
        if self.controls is not None:
            side.append(self.controls.layout())
        left = column([self.now] + trend_figures(self.trend), sizing_mode="stretch_width")
        right = column([hysteresis_figure(self.trail, self.up, self.down)] + side)
        return column(head, row(left, right, sizing_mode="stretch_width"), Div(text="<h3>settings</h3>"), self.settings,
                      sizing_mode="stretch_width")

    def update(self):
        new = self.poller.since(self.seq)
        if not new:
            if self.poller.error:
                set_text(self.now, f"<b>link: {html.escape(self.poller.error)}</b>")
            return
        self.seq = new[-1][0]
        rows = [trend_row(self.regmap, t, v) for _, t, v in new]
        self.trend.stream({c: [r[c] for r in rows] for c in TREND_COLUMNS}, rollover=self.rollover)
        self.trail.stream({"h": [r["h"] for r in rows], "p2": [r["p2"] for r in rows]}, rollover=self.rollover // 2)
        t, v = new[-1][1], new[-1][2]
        set_text(self.now, f"t = {t:.1f} s &nbsp; height <b>{rows[-1]['h']:.3f}</b> mm &nbsp; "
                           f"P2 {rows[-1]['p2']:.1f} kPa &nbsp; state "
                           f"<b>{self.regmap.enum_name('control_state', v['control_state'])}</b>")
        set_text(self.status, status_html(self.regmap, v, self.poller.error))
        self.show_settings(v)

    def show_settings(self, v):
        settings = {r["name"]: v[r["name"]] for r in self.regmap.table("holding")}
        if settings == self.last_settings:
            return
        self.last_settings = settings
        lines = hysteresis_lines(self.regmap, v)
        self.up.data, self.down.data = lines["up"], lines["down"]
        self.settings.text = settings_html(self.regmap, v)
        if self.controls is not None:
            self.controls.settings_changed(v)


def value_text(regmap, name, value):
    if "enum" in regmap[name]:
        return f"{regmap.enum_name(name, value)} ({value})"
    return str(value)


def settings_html(regmap, v):
    """The settings (holding registers) as a table: the learnt ones (registers.json's
    descriptions say "(learnt)") first, highlighted, then the others in address order."""
    regs = sorted(regmap.table("holding"), key=lambda r: "(learnt)" not in r["description"])
    rows = []
    for r in regs:
        learnt = "(learnt)" in r["description"]
        shade = LEARNT_SHADE if learnt else ""
        rows.append(f"<tr{shade}><td>{r['name']}</td>"
                    f"<td><b>{html.escape(value_text(regmap, r['name'], v[r['name']]))}</b></td>"
                    f"<td>{html.escape(r['unit'])}</td><td>{'learnt' if learnt else ''}</td>"
                    f"<td>{html.escape(r['description'])}</td></tr>")
    head = "".join(f"<th align='left'>{h}</th>" for h in ("setting", "value", "unit", "", "description"))
    return f"<table style='border-collapse:collapse' cellpadding='2'><tr>{head}</tr>{''.join(rows)}</table>"


def status_html(regmap, v, link_error):
    """The controller's state, faults by name, flags and counters as a small table."""
    name = regmap.enum_name
    flags = [r["name"] for r in regmap.table("discrete") if v[r["name"]]]
    rows = [("control state", name("control_state", v["control_state"])),
            ("mode", name("mode", v["mode"])), ("algorithm", name("algorithm", v["algorithm"])),
            ("algorithm 3 phase", name("alg3_phase", v["alg3_phase"])),
            ("active faults", ", ".join(regmap.bit_names("last_fault_code", v["active_fault_bits"])) or "none"),
            ("latched faults", ", ".join(regmap.bit_names("last_fault_code", v["latched_fault_bits"])) or "none"),
            ("last fault", name("last_fault_code", v["last_fault_code"])),
            ("UPlimit at target", f"{v['alg3_up_pa'] / 1000:.1f} kPa" if v["alg3_up_pa"] else "not learnt"),
            ("DPlimit at target", f"{v['alg3_down_pa'] / 1000:.1f} kPa" if v["alg3_down_pa"] else "not learnt"),
            ("sensor fault bits", f"{v['sensor_fault_bits']:04b} (bit n: channel n)"),
            ("last refused write", name("last_refusal_reason", v["last_refusal_reason"])),
            ("flags", ", ".join(flags) or "none"),
            ("fault counts", ", ".join(f"{r['name'][12:]} {v[r['name']]}" for r in regmap.table("input")
                                       if r["name"].startswith("fault_count_"))),
            ("uptime", f"{v['uptime_ms'] / 1000:.1f} s"), ("firmware", str(v["firmware_version"])),
            ("link", link_error or "ok")]
    cells = "".join(f"<tr><td>{html.escape(k)}</td><td class='lm-st-{k.replace(' ', '-')}'><b>{html.escape(str(x))}</b>"
                    f"</td></tr>" for k, x in rows)
    return f"<table>{cells}</table>"
