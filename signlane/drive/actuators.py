"""Where `signlane run` sends its commands: the car's motor driver.

An actuator is any object with
    step(command)   # command: signlane.types.Command (steering in [-1, 1], + right; throttle in
                    #   [0, 1], a target fraction of the car's top speed; state: the driver's state)
    close()         # called once at the end, after the final stop command
Built in: `print` (one JSON line per command on stdout), `udp:HOST:PORT` (one JSON datagram per
command). `module:Class` loads a user's class (importable from the current folder or the Python
path), constructed with no arguments. A safe stop (throttle 0, wheels straight, state
"stop: <why>") is always the last command an actuator gets.
"""
from __future__ import annotations

import importlib
import json
import socket
import sys
import time
from typing import IO, Protocol

from signlane.types import Command

SPECS = "print, udp:HOST:PORT or module:Class"


class ActuatorError(ValueError):
    """An actuator spec that cannot be used: str(e) is one line naming it."""


class Actuator(Protocol):
    def step(self, command: Command) -> None: ...

    def close(self) -> None: ...


def command_json(command: Command, t0: float) -> str:
    return json.dumps({"t": round(time.monotonic() - t0, 3), "steering": round(float(command.steering), 4),
                       "throttle": round(float(command.throttle), 4), "state": command.state})


class PrintActuator:
    """JSON lines ({"t": s since start, "steering", "throttle", "state"}) on stdout, flushed each."""

    def __init__(self, stream: IO[str] | None = None):
        self.stream = stream or sys.stdout
        self._t0 = time.monotonic()

    def step(self, command: Command) -> None:
        self.stream.write(command_json(command, self._t0) + "\n")
        self.stream.flush()

    def close(self) -> None:
        self.stream.flush()


class UdpActuator:
    """One UTF-8 JSON datagram per command, the same object as `print` writes."""

    def __init__(self, host: str, port: int):
        try:
            info = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
        except socket.gaierror as e:
            raise ActuatorError(f"actuator udp:{host}:{port}: cannot resolve {host!r} ({e.strerror})") from None
        self.sock = socket.socket(info[0], socket.SOCK_DGRAM)
        self.addr = info[4]
        self._t0 = time.monotonic()

    def step(self, command: Command) -> None:
        try:
            self.sock.sendto(command_json(command, self._t0).encode(), self.addr)
        except OSError:
            pass  # nobody listening (ICMP refused) must not stop the car's loop; the next command goes again

    def close(self) -> None:
        self.sock.close()


def load_actuator(spec: str) -> Actuator:
    """The actuator a spec names, or one ActuatorError line."""
    spec = spec.strip()
    if spec == "print":
        return PrintActuator()
    if spec.startswith("udp:"):
        host, sep, port = spec[4:].rpartition(":")
        if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise ActuatorError(f"actuator {spec!r}: expected udp:HOST:PORT with a port 1..65535")
        return UdpActuator(host.strip("[]"), int(port))
    module, sep, name = spec.partition(":")
    if not sep or not module or not name:
        raise ActuatorError(f"actuator {spec!r}: expected {SPECS}")
    if "" not in sys.path and "." not in sys.path:
        sys.path.insert(0, "")  # a user's motor driver beside them, as `python -m` would find it
    try:
        mod = importlib.import_module(module)
    except Exception as e:  # ImportError, or the module itself failing on import
        raise ActuatorError(f"actuator {spec!r}: cannot import {module!r} ({type(e).__name__}: {e})") from None
    cls = getattr(mod, name, None)
    if cls is None:
        raise ActuatorError(f"actuator {spec!r}: module {module!r} has no {name!r}")
    try:
        obj = cls()
    except Exception as e:
        raise ActuatorError(f"actuator {spec!r}: {name}() failed ({type(e).__name__}: {e})") from None
    missing = [m for m in ("step", "close") if not callable(getattr(obj, m, None))]
    if missing:
        raise ActuatorError(f"actuator {spec!r}: {name} has no {' or '.join(missing)}() method "
                            "(an actuator needs step(command) and close())")
    return obj
