"""leveler-monitor: a live page of a running rig or board over Modbus (docs/monitor.md).

Modules
-------
regmap    registers.json loaded (gen_regmap's loader) and decoded: words <-> named values
modbus    the Modbus client (TCP or RTU), the poller thread, the validated writes
page      the Bokeh document: trends, hysteresis lines, state, faults, settings
controls  the page's write controls (--allow-writes)
cli       command line: python -m leveler.monitor (scripts/leveler-monitor)
"""
