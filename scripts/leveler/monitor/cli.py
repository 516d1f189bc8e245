"""leveler-monitor: a live page of a running rig (Modbus TCP) or board
(Modbus RTU): trends of height with the band, P1/P2/P3 and the actuators, the
controller's state, faults, the learnt hysteresis lines and settings
(docs/monitor.md). Read-only unless --allow-writes.

  leveler-monitor --host 127.0.0.1 --port 1502            # a rig (leveler-rig)
  leveler-monitor --serial /dev/ttyUSB0 --baud 19200      # a board over RS-485
  then open http://127.0.0.1:5006/
"""
import logging
import signal
import socket
import sys

from leveler import cli as leveler_cli

from . import modbus
from .regmap import DEFAULT_PATH, RegisterMap, RegmapError

MAX_RATE_HZ = 10.0


def parse_args(argv):
    ap = leveler_cli.parser("leveler-monitor", __doc__)
    ap.add_argument("--host", default="127.0.0.1", metavar="ADDR",
                    help="the rig's Modbus TCP server address (default 127.0.0.1)")
    ap.add_argument("--port", type=int, default=1502, metavar="N", help="its Modbus TCP port (default 1502)")
    ap.add_argument("--serial", metavar="DEVICE", help="a board's serial port instead (Modbus RTU)")
    ap.add_argument("--baud", type=int, default=19200, metavar="N", help="RTU baud rate (default 19200)")
    ap.add_argument("--parity", choices=("E", "N", "O"), default="E", help="RTU parity (default E: 8E1)")
    ap.add_argument("--unit", type=int, default=1, metavar="ID", help="Modbus unit id 0..247 (default 1)")
    ap.add_argument("--rate", type=float, default=MAX_RATE_HZ, metavar="HZ",
                    help=f"polls per second, at most {MAX_RATE_HZ:g} (default {MAX_RATE_HZ:g})")
    ap.add_argument("--http-address", default="127.0.0.1", metavar="ADDR",
                    help="where the page is served (default 127.0.0.1: this computer only)")
    ap.add_argument("--http-port", type=int, default=5006, metavar="N", help="the page's port (default 5006; 0: a free one)")
    ap.add_argument("--http-port-file", metavar="FILE", help="write the page's port here once it listens")
    ap.add_argument("--allow-origin", action="append", default=[], metavar="HOST:PORT",
                    help="another host:port browsers may reach the page by (behind a proxy, another name)")
    ap.add_argument("--allow-writes", action="store_true",
                    help="offer mode, band, clear faults and settings writes on the page (default: read-only)")
    ap.add_argument("--regmap", default=DEFAULT_PATH, metavar="FILE",
                    help="the register map (default: firmware/regmap/registers.json of this tree)")
    a = ap.parse_args(argv)
    if not 0 < a.rate <= MAX_RATE_HZ:
        ap.error(f"--rate: {a.rate:g} is not in (0, {MAX_RATE_HZ:g}]")
    if not 0 <= a.unit <= 247:
        ap.error(f"--unit: {a.unit} is not in 0..247")
    if not 0 <= a.http_port <= 65535 or not 0 < a.port <= 65535:
        ap.error("--port and --http-port: 1..65535 (--http-port 0: a free one)")
    return a


def free_port(address):
    """A port the kernel has free on address now (for --http-port 0)."""
    with socket.socket(socket.AF_INET6 if ":" in address else socket.AF_INET) as s:
        s.bind((address, 0))
        return s.getsockname()[1]


def main(argv=None):
    a = parse_args(sys.argv[1:] if argv is None else argv)
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)   # a lost link is said once (modbus.Poller), not per poll
    try:
        regmap = RegisterMap(a.regmap)
    except RegmapError as e:
        print(f"leveler-monitor: error: --regmap: {e}", file=sys.stderr)
        return leveler_cli.EXIT_BAD_INPUT
    if a.serial:
        client, peer = modbus.rtu_client(a.serial, a.baud, a.parity, 1.0), f"{a.serial} {a.baud} 8{a.parity}1"
    else:
        client, peer = modbus.tcp_client(a.host, a.port, 2.0), f"{a.host}:{a.port}"
    link = modbus.Link(client, regmap, a.unit)
    try:
        link.read_all()
    except modbus.LinkError as e:
        print(f"leveler-monitor: error: {peer}: no answer ({e})", file=sys.stderr)
        return leveler_cli.EXIT_FAILED
    return serve(a, link, regmap, peer)


def serve(a, link, regmap, peer):
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server

    from .page import Page
    poller = modbus.Poller(link, a.rate)
    poller.start()
    port = a.http_port or free_port(a.http_address)
    origins = [f"{a.http_address}:{port}", f"localhost:{port}"] + a.allow_origin
    writes = link if a.allow_writes else None
    app = Application(FunctionHandler(lambda doc: Page(doc, poller, regmap, writes, a.rate)))
    try:
        server = Server({"/": app}, address=a.http_address, port=port, allow_websocket_origin=origins,
                        num_procs=1)
    except OSError as e:
        print(f"leveler-monitor: error: --http-port {port}: {e.strerror}", file=sys.stderr)
        return leveler_cli.EXIT_FAILED
    server.start()
    if a.http_port_file:
        with open(a.http_port_file, "w") as f:
            f.write(f"{port}\n")
    for sig in (signal.SIGINT, signal.SIGTERM):
        server.io_loop.asyncio_loop.add_signal_handler(sig, server.io_loop.stop)
    print(f"leveler-monitor: {peer} ({'writes allowed' if a.allow_writes else 'read-only'}) on "
          f"http://{a.http_address}:{port}/", file=sys.stderr, flush=True)
    server.io_loop.start()
    poller.stop()
    return leveler_cli.EXIT_OK
