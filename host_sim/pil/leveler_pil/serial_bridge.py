"""USART1 of the emulated board as a byte stream a real Modbus RTU master
(pymodbus's serial client, via pyserial's socket:// port) can open: the
emulator runs in a thread; bytes from the master reach the image one
character time apart in emulated time, the image's bytes go straight out.

(A pseudo-terminal was the first choice; pyserial's tcsetattr on a Linux pty
fails with EINVAL for 8E1 once the pty has been opened, so the byte stream
is a local TCP socket carrying the same RTU frames.)"""

from __future__ import annotations

import socket
import threading


class SerialBridge:
    def __init__(self, pil):
        self.pil = pil
        self._listen = socket.socket()
        self._listen.bind(("127.0.0.1", 0))
        self._listen.listen(1)
        self.url = f"socket://127.0.0.1:{self._listen.getsockname()[1]}"
        self._conn = None
        self._stop = threading.Event()
        self._thread = None
        self.error = None

    def _read(self):
        if self._conn is None:
            try:
                self._conn, _ = self._listen.accept()
                self._conn.setblocking(False)
            except BlockingIOError:
                return b""
        try:
            return self._conn.recv(512)
        except BlockingIOError:
            return b""

    def _write(self, data):
        if self._conn is not None:
            self._conn.sendall(data)

    def _run(self):
        try:
            while not self._stop.is_set():
                self.pil.run_for(0.01)
        except Exception as e:  # raised again on exit
            self.error = e

    def __enter__(self):
        self._listen.setblocking(False)
        self.pil.serial_source = self._read
        self.pil.serial_sink = self._write
        self._thread = threading.Thread(target=self._run, name="pil-emulator", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.pil.serial_source = self.pil.serial_sink = None
        for s in (self._conn, self._listen):
            if s is not None:
                s.close()
        if self.error is not None and exc[0] is None:
            raise self.error
