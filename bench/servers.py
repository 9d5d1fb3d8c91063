"""Servers and lines for the benchmarks, each in its own process (``python bench/servers.py ...``).

The parent reads one ``READY ...`` line from stdout and stops the child by closing its stdin
(the child exits when stdin reaches EOF, or after ``--max-seconds``). Running them in separate
processes keeps the server's work off the client's interpreter (and its GIL).

``tcp MODEL drivemap``      the generated simulator (``generated/MODEL/simulator.py``) on 127.0.0.1
``tcp MODEL simdevice``     a plain pymodbus ``SimDevice`` server holding the same register words
``serial MODEL PORT BAUD``  the generated simulator (realistic timing) on a serial device path
``lean MODEL PORT BAUD``    a lean reference device on a serial device path: one loop in its own process
                            that reads a request (framed by pymodbus's ``FramerRTU``), waits exactly the
                            simulator's processing time from the request's last byte (sleep, then spin the
                            last 0.3 ms) and writes the very bytes the generated simulator answers
                            (``Simulator.handle``, realistic timing)
``line BAUD``               a paced :class:`VirtualSerialLine` (8N1, 10 bits per byte) that records its
                            traffic; stdin commands ``clear`` and ``dump FILE`` (JSON of the timestamped
                            chunks per direction, captured and delivered), each answered by ``OK``
"""

from __future__ import annotations

import asyncio
import importlib
import json
import os
import select
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import ROOT  # noqa: E402


def same_words(model: str) -> dict[int, int]:
    """address -> word of every address ``read_all`` reads, as the generated simulator answers it."""
    client_mod = importlib.import_module(f"drivemap_models.{model}.client")
    sim = importlib.import_module(f"drivemap_models.{model}.simulator").Simulator([1])
    words: dict[int, int] = {}
    for req in client_mod.Client.plan():
        pdu = bytes([0x03]) + req.address.to_bytes(2, "big") + req.count.to_bytes(2, "big")
        reply = sim.handle(1, pdu)
        assert reply is not None and reply[0] == 0x03, reply
        for i in range(req.count):
            words.setdefault(req.address + i, int.from_bytes(reply[2 + 2 * i: 4 + 2 * i], "big"))
    return words


async def _serve_tcp(model: str, kind: str, stop: asyncio.Event) -> None:
    from pymodbus.framer import FramerType
    from pymodbus.server import ModbusTcpServer
    from pymodbus.simulator import DataType, SimData, SimDevice

    if kind == "drivemap":
        from drivemap.runtime.sim.serve import SimServer

        sim = importlib.import_module(f"drivemap_models.{model}.simulator").Simulator([1])
        server = SimServer(sim, tcp=("127.0.0.1", 0))
        await server.start()
        assert server.address is not None
        print("READY", *server.address, flush=True)
        await stop.wait()
        await server.stop()
        return
    words = same_words(model)
    blocks: list[SimData] = []
    run: list[int] = []
    start = -1
    for address in sorted(words):
        if run and address != start + len(run):
            blocks.append(SimData(address=start, values=run, datatype=DataType.REGISTERS))
            run = []
        if not run:
            start = address
        run.append(words[address])
    if run:
        blocks.append(SimData(address=start, values=run, datatype=DataType.REGISTERS))
    plain = ModbusTcpServer([SimDevice(id=1, simdata=blocks)], framer=FramerType.SOCKET, address=("127.0.0.1", 0))
    await plain.serve_forever(background=True)
    sockets = getattr(plain.transport, "sockets", None) or []
    host, port = sockets[0].getsockname()[:2]
    print("READY", host, port, flush=True)
    await stop.wait()
    await plain.shutdown()  # type: ignore[no-untyped-call]


async def _serve_serial(model: str, port: str, baud: int, stop: asyncio.Event) -> None:
    from drivemap.runtime.sim.serve import SimServer

    sim = importlib.import_module(f"drivemap_models.{model}.simulator").Simulator([1], realistic_timing=True)
    server = SimServer(sim, serial=port, mode="rtu", baudrate=baud, parity="none", stop_bits=1, data_bits=8)
    await server.start()
    print("READY", port, sim.reply_delay(), flush=True)
    await stop.wait()
    await server.stop()


def _lean_device(model: str, port: str, baud: int, max_seconds: float) -> None:
    """The reference device: no event loop, no server framework, a precise processing delay."""
    from pymodbus.framer import FramerRTU
    from pymodbus.pdu import DecodePDU

    sim = importlib.import_module(f"drivemap_models.{model}.simulator").Simulator([1], realistic_timing=True)
    delay = sim.reply_delay()
    framer = FramerRTU(DecodePDU(True))
    fd = os.open(port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)  # the line keeps its ptys raw
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    print("READY", port, delay, flush=True)
    poller = select.poll()
    poller.register(fd, select.POLLIN)
    buf = b""
    end = time.monotonic() + max_seconds
    try:
        while not done.is_set() and time.monotonic() < end:
            if not poller.poll(100):
                continue
            try:
                data = os.read(fd, 512)
            except BlockingIOError:
                continue
            arrived = time.monotonic()
            buf += data
            while buf:
                used, dev_id, _tid, pdu = framer.decode(buf)
                if not used:
                    break
                buf = buf[used:]
                if not pdu:
                    continue
                reply = sim.handle(dev_id, pdu)
                if reply is None:
                    continue
                frame = framer.encode(reply, dev_id, 0)
                due = arrived + delay
                if (left := due - time.monotonic() - 0.0003) > 0:
                    time.sleep(left)
                while time.monotonic() < due:
                    pass
                os.write(fd, frame)
    finally:
        os.close(fd)


def _stdin_closed(loop: asyncio.AbstractEventLoop, stop: asyncio.Event) -> None:
    sys.stdin.read()
    loop.call_soon_threadsafe(stop.set)


async def _main_async(args: list[str], max_seconds: float) -> None:
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    threading.Thread(target=_stdin_closed, args=(loop, stop), daemon=True).start()
    loop.call_later(max_seconds, stop.set)
    if args[0] == "tcp":
        await _serve_tcp(args[1], args[2], stop)
    else:
        await _serve_serial(args[1], args[2], int(args[3]), stop)


def main(argv: list[str]) -> int:
    max_seconds = 600.0
    if "--max-seconds" in argv:
        i = argv.index("--max-seconds")
        max_seconds = float(argv[i + 1])
        argv = argv[:i] + argv[i + 2:]
    if argv[0] == "line":
        from drivemap.testing.vserial import VirtualSerialLine

        done = threading.Event()
        with VirtualSerialLine(int(argv[1]), pace=True, capture=True, name="bench") as line:

            def commands() -> None:
                for command in sys.stdin:
                    word, _, arg = command.strip().partition(" ")
                    if word == "clear":
                        line.clear()
                    elif word == "dump":
                        chunks = {f"{d} {which}": [(t, len(b)) for t, b in line.chunks(d, which)]
                                  for d in ("to_device", "to_master") for which in ("captured", "delivered")}
                        Path(arg).write_text(json.dumps(chunks), encoding="utf-8")
                    print("OK", flush=True)
                done.set()

            threading.Thread(target=commands, daemon=True).start()
            print("READY", line.master_port, line.device_port, flush=True)
            done.wait(max_seconds)
        return 0
    if argv[0] == "lean":
        _lean_device(argv[1], argv[2], int(argv[3]), max_seconds)
        return 0
    asyncio.run(_main_async(argv, max_seconds))
    return 0


class Child:
    """A child process started with ``servers.py`` args; ``fields`` are the words after READY."""

    def __init__(self, *args: str, max_seconds: float = 300.0, ready_timeout: float = 20.0) -> None:
        cmd = [sys.executable, str(HERE / "servers.py"), *args, "--max-seconds", str(max_seconds)]
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, cwd=str(ROOT))
        self.fields: list[str] = []
        result: list[str] = []
        reader = threading.Thread(target=lambda: result.append(self.proc.stdout.readline() if self.proc.stdout else ""),
                                  daemon=True)
        reader.start()
        reader.join(ready_timeout)
        line = result[0] if result else ""
        if not line.startswith("READY"):
            self.close()
            err = self.proc.stderr.read() if self.proc.stderr else ""
            raise RuntimeError(f"servers.py {' '.join(args)} did not start: {line!r} {err[-2000:]}")
        self.fields = line.split()[1:]

    def command(self, text: str, timeout: float = 20.0) -> str:
        """Send one command line on stdin; the child's one-line answer."""
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(text + "\n")
        self.proc.stdin.flush()
        result: list[str] = []
        reader = threading.Thread(target=lambda: result.append(self.proc.stdout.readline() if self.proc.stdout else ""),
                                  daemon=True)
        reader.start()
        reader.join(timeout)
        if not result:
            raise RuntimeError(f"servers.py: no answer to {text!r}")
        return result[0].strip()

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                if self.proc.stdin:
                    self.proc.stdin.close()
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)

    def __enter__(self) -> Child:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
