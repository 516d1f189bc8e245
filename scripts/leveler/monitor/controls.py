"""The page's write controls (leveler-monitor --allow-writes): mode, band,
clear faults, and commissioning (any writable setting). Each is one Modbus
write of the register map, validated whole by the firmware; a refusal shows
the firmware's reason (last_refusal_reason's name, modbus.py).
"""
import html

from bokeh.layouts import column, row
from bokeh.models import Button, Div, Select, TextInput

from .modbus import LinkError, WriteRefused, say
from .regmap import RegmapError

UM_PER_MM = 1000


class Controls:
    def __init__(self, regmap, link):
        self.regmap, self.link = regmap, link
        modes = list(regmap["mode"]["enum"])
        self.mode = Select(title="mode", options=modes, value=modes[0], css_classes=["lm-mode"], width=140)
        self.lower = TextInput(title="band lower (mm)", css_classes=["lm-band-lower"], width=140)
        self.upper = TextInput(title="band upper (mm)", css_classes=["lm-band-upper"], width=140)
        names = regmap.writable("holding")
        self.setting = Select(title="setting (commissioning)", options=names, value=names[0],
                              css_classes=["lm-setting"], width=220)
        self.value = TextInput(title="value", css_classes=["lm-setting-value"], width=140)
        self.result = Div(text="writes go to the firmware, which validates them", name="write_result",
                          css_classes=["lm-result"], width=460)
        self.buttons = {}
        for key, label, fn in (("mode", "set mode", self.write_mode), ("band", "set band", self.write_band),
                               ("clear", "clear faults", self.clear_faults),
                               ("setting", "write setting", self.write_setting)):
            self.buttons[key] = Button(label=label, css_classes=[f"lm-{key}-set"], width=120)
            self.buttons[key].on_click(fn)
        self.setting.on_change("value", lambda attr, old, new: self.show_setting())
        self.current = None

    def layout(self):
        b = self.buttons
        return column(Div(text="<h3>writes (--allow-writes)</h3>"), row(self.mode, b["mode"]),
                      row(self.lower, self.upper, b["band"]), b["clear"], row(self.setting, self.value, b["setting"]),
                      self.result)

    def settings_changed(self, values):
        """New settings read: fill the inputs the first time (and the selected setting's value)."""
        first = self.current is None
        self.current = values
        if first:
            self.mode.value = self.regmap.enum_name("mode", values["mode"])
            self.lower.value = f"{values['band_lower_um'] / UM_PER_MM:.3f}"
            self.upper.value = f"{values['band_upper_um'] / UM_PER_MM:.3f}"
            self.show_setting()

    def show_setting(self):
        r = self.regmap[self.setting.value]
        self.value.title = f"value ({r['unit']}; {r['range'][0]}..{r['range'][1]})"
        if self.current is not None:
            v = self.current[r["name"]]
            self.value.value = self.regmap.enum_name(r["name"], v) if "enum" in r else str(v)

    def write(self, values, what):
        try:
            self.link.write(values)
        except WriteRefused as e:
            self.say(f"<span style='color:firebrick'>refused: {html.escape(what)}: <b class='lm-refusal'>"
                     f"{html.escape(e.reason)}</b></span>", f"{what}: refused: {e.reason}")
            return
        except (LinkError, RegmapError) as e:
            self.say(f"<span style='color:firebrick'>not written: {html.escape(str(e))}</span>", f"{what}: {e}")
            return
        self.say(f"<span style='color:green'>written: {html.escape(what)}</span>", f"{what}: written")

    def say(self, text, log):
        self.result.text = text
        say(f"write {log}")

    def write_mode(self):
        self.write({"mode": self.regmap["mode"]["enum"][self.mode.value]}, f"mode = {self.mode.value}")

    def write_band(self):
        try:
            lo, hi = (round(float(w.value) * UM_PER_MM) for w in (self.lower, self.upper))
        except ValueError:
            self.say("<span style='color:firebrick'>band: give both edges in mm</span>", "band: not numbers")
            return
        self.write({"band_lower_um": lo, "band_upper_um": hi}, f"band {lo}..{hi} um")

    def clear_faults(self):
        self.write({"clear_faults": 1}, "clear faults")

    def write_setting(self):
        name, text = self.setting.value, self.value.value.strip()
        enum = self.regmap[name].get("enum", {})
        try:
            value = enum[text] if text in enum else float(text)
        except ValueError:
            known = f" or one of {', '.join(enum)}" if enum else ""
            self.say(f"<span style='color:firebrick'>{html.escape(name)}: {html.escape(text)!s} is not a number"
                     f"{html.escape(known)}</span>", f"{name}: bad value {text!r}")
            return
        self.write({name: value}, f"{name} = {text}")
