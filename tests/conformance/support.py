"""Conformance tests: fly the SITL with tools nobody here wrote (MAVSDK, MAVProxy, pymavlink).
This module holds their helpers; conftest.py makes it importable as ``conformance_support``.

Each test starts its own vehicle in a temporary folder and stops it (its whole process group)
afterwards. By default the vehicle is the embedded SITL, ``lander sitl --autopilot
ardupilot|px4``, listening on a free TCP port of 127.0.0.1 (and, as PX4, sending unasked to
two free UDP ports, as PX4 SITL sends to 14540 and 14550), at ``CONFORMANCE_SPEEDUP`` (default
10) times real time.

The same scenarios run against ArduPilot's own Copter SITL when ``CONFORMANCE_ARDUCOPTER``
names an ``arducopter`` binary (built outside this repository), optionally with
``CONFORMANCE_ARDUCOPTER_DEFAULTS`` = its ``copter.parm``; then every ``ardupilot`` case
flies the real autopilot (the ``px4`` cases fly the embedded PX4 personality unless
CONFORMANCE_PX4, below, names PX4's):

    CONFORMANCE_ARDUCOPTER=.../build/sitl/bin/arducopter \\
    CONFORMANCE_ARDUCOPTER_DEFAULTS=.../Tools/autotest/default_params/copter.parm \\
        .venv/bin/python -m pytest tests/conformance -k ardupilot

Likewise every ``px4`` case flies PX4's own SITL with its SIH quadrotor (airframe 10040) when
``CONFORMANCE_PX4`` names a ``px4`` SITL binary (``make px4_sitl_default`` in a PX4-Autopilot
checkout, outside this repository); ``CONFORMANCE_PX4_ETC`` is its ``etc`` folder (default:
``build/px4_sitl_default/etc`` beside ``bin/px4``), ``CONFORMANCE_PX4_SPEEDUP`` its
PX4_SIM_SPEED_FACTOR (default 5; SIH runs in lockstep at that factor). PX4 SITL has fixed
ports: it sends to UDP 127.0.0.1:14540 (SDKs) and 14550 (ground stations) and serves no TCP,
so these must be free and the cases run one at a time:

    CONFORMANCE_PX4=.../build/px4_sitl_default/bin/px4 \\
        .venv/bin/python -m pytest tests/conformance -k px4

Timeouts are stated in simulated seconds and turned into generous wall-clock limits
(``Vehicle.wall``); tests wait on conditions, never on fixed sleeps, and assert no timings.
"""

from __future__ import annotations

import asyncio
import math
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

SPEEDUP = float(os.environ.get("CONFORMANCE_SPEEDUP", "10"))
ARDUCOPTER = os.environ.get("CONFORMANCE_ARDUCOPTER", "")
ARDUCOPTER_DEFAULTS = os.environ.get("CONFORMANCE_ARDUCOPTER_DEFAULTS", "")
ARDUCOPTER_SPEEDUP = float(os.environ.get("CONFORMANCE_ARDUCOPTER_SPEEDUP", "5"))
PX4 = os.environ.get("CONFORMANCE_PX4", "")
PX4_ETC = os.environ.get("CONFORMANCE_PX4_ETC", "")
PX4_SPEEDUP = float(os.environ.get("CONFORMANCE_PX4_SPEEDUP", "5"))
# PX4 SITL instance 0: UDP ports it binds (SDK link, GCS link, payload, gimbal, SIH display)
# and the two it sends to unasked (an SDK's udpin, a ground station's).
PX4_BOUND = (14580, 18570, 14280, 13030, 19450)
PX4_SDK_PORT, PX4_GCS_PORT = 14540, 14550

# Where every vehicle starts: lat, lon (degrees), altitude (m AMSL).
HOME = (47.397742, 8.545594, 488.0)


# --------------------------------------------------------------------------- processes


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A port of 127.0.0.1 that is free now, for TCP (default) or UDP."""
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def port_is_free(port: int, kind: int = socket.SOCK_STREAM) -> bool:
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
        return True


def start_process(argv: list[str], cwd: Path, log: Path, **kwargs) -> subprocess.Popen:
    """Start ``argv`` in its own session (so its whole process group can be stopped)."""
    env = {**os.environ, "HOME": str(cwd), "PYTHONUNBUFFERED": "1", **kwargs.pop("env", {})}
    with open(log, "wb") as out:  # the child keeps its own descriptor
        return subprocess.Popen(
            argv,
            cwd=cwd,
            env=env,
            stdout=kwargs.pop("stdout", out),
            stderr=kwargs.pop("stderr", subprocess.STDOUT),
            stdin=kwargs.pop("stdin", subprocess.DEVNULL),
            start_new_session=True,
            **kwargs,
        )


def stop_process(proc: subprocess.Popen) -> None:
    """Stop a process we started, with everything in its process group."""
    for sig, grace in ((signal.SIGTERM, 10), (signal.SIGKILL, 10)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        try:
            proc.wait(timeout=grace)
            # the leader is gone; make sure no child of it lingers in the group
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            break
        except subprocess.TimeoutExpired:
            continue
    if proc.poll() is None:
        proc.wait(timeout=10)


def wait_for_tcp(port: int, timeout: float, proc: subprocess.Popen, log: Path) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise AssertionError(f"exited with {proc.returncode} before listening:\n{tail(log)}")
        with socket.socket() as probe:
            probe.settimeout(0.5)
            if probe.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.1)
    raise AssertionError(f"nothing listens on 127.0.0.1:{port} after {timeout} s:\n{tail(log)}")


def tail(path: Path, lines: int = 40) -> str:
    try:
        text = path.read_text(errors="replace")
    except OSError:
        return f"({path} unreadable)"
    return "\n".join(text.splitlines()[-lines:])


# --------------------------------------------------------------------------- vehicles


@dataclass
class Vehicle:
    """A running vehicle under test."""

    autopilot: str  # "ardupilot" or "px4"
    real: bool  # True: the autopilot's own SITL binary; False: the embedded `lander sitl`
    tcp_port: int | None  # where it listens for MAVLink TCP clients (real PX4: nowhere)
    # PX4 only: UDP ports of 127.0.0.1 it sends to unasked, as PX4 SITL sends to 14540 (an
    # SDK's udpin) and 14550 (a ground station's).
    sdk_port: int | None
    gcs_port: int | None
    speedup: float
    workdir: Path
    log: Path
    proc: subprocess.Popen = field(repr=False)

    def wall(self, sim_seconds: float) -> float:
        """A generous wall-clock limit for something that takes ``sim_seconds`` simulated."""
        return 30.0 + 4.0 * sim_seconds / self.speedup

    def sim_sleep(self, sim_seconds: float) -> float:
        """Wall seconds that ``sim_seconds`` of simulated time take (for retry intervals)."""
        return sim_seconds / self.speedup

    @property
    def name(self) -> str:
        if self.real and self.autopilot == "px4":
            return (
                f"PX4's px4 SITL with SIH (udp 127.0.0.1:{self.sdk_port} and "
                f"{self.gcs_port}, log {self.log})"
            )
        if self.real:
            what = "ArduPilot's arducopter SITL"
        else:
            what = f"lander sitl --autopilot {self.autopilot}"
        return f"{what} (tcp 127.0.0.1:{self.tcp_port}, log {self.log})"

    def alive(self) -> None:
        if self.proc.poll() is not None:
            raise AssertionError(
                f"{self.name} exited with {self.proc.returncode}:\n{tail(self.log)}"
            )


def start_embedded(autopilot: str, workdir: Path, speedup: float = SPEEDUP) -> Vehicle:
    tcp = free_port()
    sdk = gcs = None
    log = workdir / f"lander-sitl-{autopilot}.log"
    argv = [
        sys.executable, "-m", "autonomy", "sitl",
        "--autopilot", autopilot,
        "--tcp", f"127.0.0.1:{tcp}",
        "--speedup", f"{speedup:g}",
        "--home", ",".join(str(v) for v in HOME),
    ]  # fmt: skip
    if autopilot == "px4":
        sdk, gcs = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_DGRAM)
        argv += ["--udp-out", f"127.0.0.1:{sdk}", "--udp-out", f"127.0.0.1:{gcs}"]
    proc = start_process(argv, workdir, log)
    vehicle = Vehicle(autopilot, False, tcp, sdk, gcs, speedup, workdir, log, proc)
    wait_for_tcp(tcp, 60, proc, log)
    return vehicle


def start_arducopter(workdir: Path) -> Vehicle:
    # arducopter -I N serves MAVLink on TCP 5760 + 10 N (and uses 5760..5763 + 10 N).
    for instance in range(1, 60):
        base = 5760 + 10 * instance
        if all(port_is_free(base + k) for k in range(4)):
            break
    else:
        raise AssertionError("no free arducopter instance between 1 and 59")
    log = workdir / "arducopter.log"
    argv = [
        str(Path(ARDUCOPTER).expanduser()),
        "--model", "quad",
        "--speedup", f"{ARDUCOPTER_SPEEDUP:g}",
        f"-I{instance}",
        "--home", ",".join(str(v) for v in HOME) + ",0",
        "--wipe",
    ]  # fmt: skip
    if ARDUCOPTER_DEFAULTS:
        argv += ["--defaults", str(Path(ARDUCOPTER_DEFAULTS).expanduser())]
    proc = start_process(argv, workdir, log)
    vehicle = Vehicle("ardupilot", True, base, None, None, ARDUCOPTER_SPEEDUP, workdir, log, proc)
    wait_for_tcp(base, 60, proc, log)
    return vehicle


def wait_for_line(log: Path, text: str, timeout: float, proc: subprocess.Popen) -> None:
    """Wait until ``text`` appears in the log the process writes."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise AssertionError(f"exited with {proc.returncode}:\n{tail(log)}")
        try:
            if text in log.read_text(errors="replace"):
                return
        except OSError:
            pass
        time.sleep(0.1)
    raise AssertionError(f"no {text!r} in {log} after {timeout} s:\n{tail(log)}")


def start_px4(workdir: Path, speedup: float = PX4_SPEEDUP) -> Vehicle:
    """PX4's SITL with the SIH quadrotor (instance 0), placed at HOME, in ``workdir``/rootfs
    (its parameters, mission store and logs start empty), at PX4_SIM_SPEED_FACTOR
    ``speedup``."""
    udp = socket.SOCK_DGRAM
    busy = [p for p in (*PX4_BOUND, PX4_SDK_PORT, PX4_GCS_PORT) if not port_is_free(p, udp)]
    if busy:
        raise AssertionError(f"PX4 SITL needs UDP ports {busy} of 127.0.0.1, which are in use")
    binary = Path(PX4).expanduser().resolve()
    etc = Path(PX4_ETC).expanduser() if PX4_ETC else binary.parent.parent / "etc"
    rootfs = workdir / "rootfs"
    rootfs.mkdir()
    log = workdir / "px4.log"
    env = {
        "PX4_SYS_AUTOSTART": "10040",  # SIH quadrotor X
        "PX4_SIMULATOR": "sihsim",
        "PX4_SIM_MODEL": "sihsim_quadx",
        "PX4_SIM_SPEED_FACTOR": f"{speedup:g}",
        "PX4_HOME_LAT": str(HOME[0]),
        "PX4_HOME_LON": str(HOME[1]),
        "PX4_HOME_ALT": str(HOME[2]),
        "HEADLESS": "1",
    }
    proc = start_process([str(binary), "-d", "-w", str(rootfs), str(etc)], rootfs, log, env=env)
    vehicle = Vehicle(
        "px4", True, None, PX4_SDK_PORT, PX4_GCS_PORT, speedup, workdir, log, proc
    )
    try:
        wait_for_line(log, "Startup script returned successfully", 60, proc)
    except AssertionError:
        stop_process(proc)
        raise
    return vehicle


def start_vehicle(
    autopilot: str,
    workdir: Path,
    px4_speedup: float | None = None,
    speedup: float | None = None,
) -> Vehicle:
    """The vehicle under test: the autopilot's own SITL if CONFORMANCE_ARDUCOPTER or
    CONFORMANCE_PX4 names it, else the embedded SITL in that personality. ``px4_speedup``
    caps a real PX4's speed-up; ``speedup`` caps the embedded SITL's (``CONFORMANCE_SPEEDUP``),
    for clients that stream at a fixed wall-clock rate (MAVSDK's offboard setpoints, 20 Hz)."""
    if autopilot == "ardupilot" and ARDUCOPTER:
        return start_arducopter(workdir)
    if autopilot == "px4" and PX4:
        return start_px4(workdir, min(PX4_SPEEDUP, px4_speedup or PX4_SPEEDUP))
    return start_embedded(autopilot, workdir, min(SPEEDUP, speedup or SPEEDUP))



# --------------------------------------------------------------------------- MAVSDK




def mavsdk_address(vehicle: Vehicle) -> str:
    """How a MAVSDK user reaches this vehicle: ArduPilot's TCP port; for PX4 the UDP port it
    sends to unasked (as PX4 SITL sends to udpin://0.0.0.0:14540)."""
    if vehicle.autopilot == "px4":
        return f"udpin://127.0.0.1:{vehicle.sdk_port}"
    return f"tcpout://127.0.0.1:{vehicle.tcp_port}"


async def within(aw, timeout: float, what: str):
    """``await aw``, failing the test when it takes more than ``timeout`` wall seconds."""
    try:
        return await asyncio.wait_for(aw, timeout)
    except asyncio.TimeoutError:
        raise AssertionError(f"{what}: no answer within {timeout:.0f} s") from None


async def until(stream, condition, timeout: float, what: str):
    """First item of a telemetry stream that satisfies ``condition``."""
    last = []

    async def scan():
        async for item in stream:
            last[:] = [item]
            if condition(item):
                return item

    try:
        return await asyncio.wait_for(scan(), timeout)
    except asyncio.TimeoutError:
        seen = last[0] if last else "nothing"
        raise AssertionError(f"{what}: not reached in {timeout:.0f} s; last seen: {seen}") from None


async def mode(tel, name: str, timeout: float):
    """Wait for MAVSDK's flight mode ``name`` (telemetry ``tel``), up to ``timeout`` s."""
    return await until(tel.flight_mode(), lambda m: m.name == name, timeout, f"mode {name}")


def collect_status_texts(tel) -> tuple[asyncio.Task, list[str]]:
    """Start collecting the vehicle's STATUSTEXTs: (the task, to cancel at the end; the texts
    so far)."""
    texts: list[str] = []

    async def collect():
        async for t in tel.status_text():
            texts.append(t.text)

    return asyncio.create_task(collect()), texts


async def connect(vehicle: Vehicle, mavsdk_server):
    """A MAVSDK System connected (through the ``mavsdk_server`` fixture) to ``vehicle``."""
    from mavsdk import System

    host, port = mavsdk_server(mavsdk_address(vehicle))
    drone = System(mavsdk_server_address=host, port=port)
    await within(drone.connect(), vehicle.wall(10), "gRPC connection to mavsdk_server")
    await until(
        drone.core.connection_state(),
        lambda s: s.is_connected,
        vehicle.wall(30),
        f"MAVSDK discovers {vehicle.name}",
    )
    return drone


async def arm_and_takeoff(drone, vehicle: Vehicle) -> None:
    """Arm and take off to MAVSDK's takeoff altitude. While the estimator settles the
    autopilot refuses (ArduPilot passes its pre-arm check in STABILIZE before GUIDED, which
    takeoff needs, has a position estimate, and disarms again if left on the ground): retry,
    within limits."""
    from mavsdk.action import ActionError

    w, tel = vehicle.wall, drone.telemetry
    loop = asyncio.get_running_loop()
    deadline, refusals = loop.time() + w(90), []
    while True:
        try:
            if not await until(tel.armed(), lambda a: True, w(10), "armed state"):
                await within(drone.action.arm(), w(10), "arm")
                await until(tel.armed(), lambda a: a, w(10), "armed")
            await within(drone.action.takeoff(), w(20), "takeoff")
            return
        except ActionError as exc:
            refusals.append(str(exc))
            if loop.time() > deadline:
                raise AssertionError(f"arm/takeoff refused until then: {refusals}") from None
            await asyncio.sleep(vehicle.sim_sleep(2.0))


def start_mavsdk_server(address: str, workdir: Path) -> tuple[subprocess.Popen, Path, int]:
    """The mavsdk_server binary shipped in the mavsdk wheel, on a free gRPC port, in its own
    session (System() would start it as a plain child we could not stop as a group)."""
    from importlib.resources import files

    binary = Path(str(files("mavsdk.bin") / "mavsdk_server"))
    assert binary.is_file(), "the mavsdk wheel has no mavsdk_server binary"
    port = free_port()
    log = workdir / "mavsdk_server.log"
    argv = [str(binary), "-p", str(port), "--sysid", "245", "--compid", "190", address]
    proc = start_process(argv, workdir, log)
    try:
        wait_for_tcp(port, 30, proc, log)
    except AssertionError:
        stop_process(proc)
        raise
    return proc, log, port



# --------------------------------------------------------------------------- MAVProxy


class MavProxy:
    """MAVProxy driven through its console (stdin), its output read line by line."""

    def __init__(self, master: str, workdir: Path, extra: list[str] | None = None) -> None:
        self.workdir = workdir
        self.log = workdir / "mavproxy.log"
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self._cursor = 0
        workdir.mkdir(exist_ok=True)
        mavproxy = Path(sys.executable).with_name("mavproxy.py")
        argv = [
            sys.executable, str(mavproxy),
            "--master", master,
            "--state-basedir", str(workdir),
            "--aircraft", "conformance",
            *(extra or []),
        ]  # fmt: skip
        self.proc = start_process(
            argv, workdir, self.log, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
            bufsize=1,
        )
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        start = time.monotonic()
        with open(self.log, "a") as log:
            for line in self.proc.stdout:
                log.write(f"{time.monotonic() - start:8.2f} {line}")
                log.flush()
                with self._cond:
                    self.lines.append(line.rstrip("\n"))
                    self._cond.notify_all()
        with self._cond:
            self._cond.notify_all()

    def send(self, command: str) -> None:
        """Type one console command."""
        if self.proc.poll() is not None:
            raise AssertionError(f"MAVProxy exited ({self.proc.returncode}):\n{self.recent()}")
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()

    def mark(self) -> int:
        """Position in the output from which the next expect() starts."""
        with self._cond:
            self._cursor = len(self.lines)
            return self._cursor

    def expect(self, pattern: str, timeout: float, what: str, since: int | None = None):
        """Wait for a line matching ``pattern`` (regex, searched) after the mark; returns the
        match. Lines after it remain for the next expect()."""
        rx = re.compile(pattern)
        end = time.monotonic() + timeout
        start = self._cursor if since is None else since
        with self._cond:
            i = start
            while True:
                while i < len(self.lines):
                    m = rx.search(self.lines[i])
                    i += 1
                    if m:
                        self._cursor = i
                        return m
                left = end - time.monotonic()
                if left <= 0 or (self.proc.poll() is not None and i >= len(self.lines)):
                    raise AssertionError(
                        f"MAVProxy: {what}: no line matching {pattern!r} in {timeout:.0f} s"
                        f"; output since:\n{self.recent(since=start)}"
                    )
                self._cond.wait(min(left, 0.5))

    def output(self, since: int = 0) -> list[str]:
        with self._cond:
            return list(self.lines[since:])

    def recent(self, since: int | None = None, limit: int = 60) -> str:
        lines = self.output(0 if since is None else since)
        return "\n".join(lines[-limit:])

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self.proc.stdin.write("exit\n")
                self.proc.stdin.flush()
                self.proc.stdin.close()
                self.proc.wait(timeout=10)
            except (OSError, subprocess.TimeoutExpired):
                pass
        stop_process(self.proc)
        self._reader.join(timeout=5)




def mavproxy_master(vehicle: Vehicle) -> str:
    """MAVProxy's --master for this vehicle: ArduPilot's TCP port; for PX4 the UDP port it
    sends to unasked (as PX4 SITL sends to a ground station's 14550)."""
    if vehicle.autopilot == "px4":
        return f"udpin:127.0.0.1:{vehicle.gcs_port}"
    return f"tcp:127.0.0.1:{vehicle.tcp_port}"


# --------------------------------------------------------------------------- pymavlink


class Monitor:
    """A pymavlink reader on a background thread that keeps the latest message of each type
    (and every STATUSTEXT) and lets the test wait on conditions over them.

    ``Monitor("udpin:127.0.0.1:PORT")`` listens for what MAVProxy forwards (``--out``) and
    never sends; ``Monitor("tcp:127.0.0.1:PORT", heartbeat=True)`` is a ground station of its
    own that sends a GCS HEARTBEAT every second. ``keep`` names message types of which every
    one is kept (in ``kept``), not only the latest."""

    def __init__(self, url: str, heartbeat: bool = False, keep: tuple[str, ...] = ()) -> None:
        from pymavlink import mavutil

        self.mavutil = mavutil
        self.conn = mavutil.mavlink_connection(url, source_system=254, source_component=190)
        self.latest: dict[str, object] = {}
        self.kept: dict[str, list] = {kind: [] for kind in keep}  # every one of these types
        self.counts: dict[str, int] = {}
        self.texts: list[str] = []
        self.positions: list[tuple[float, float, float]] = []  # lat, lon, relative alt (m)
        self._cond = threading.Condition()
        self._heartbeat = heartbeat
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        mavlink = self.mavutil.mavlink
        next_beat = 0.0
        while not self._stop.is_set():
            if self._heartbeat and time.monotonic() >= next_beat:
                next_beat = time.monotonic() + 1.0
                self.conn.mav.heartbeat_send(
                    mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0
                )
            try:
                msg = self.conn.recv_match(blocking=True, timeout=0.2)
            except (OSError, ConnectionError):
                time.sleep(0.05)
                continue
            if msg is None:
                continue
            kind = msg.get_type()
            if kind == "BAD_DATA":
                continue
            if msg.get_srcSystem() != 1 and kind != "HEARTBEAT":
                continue
            if kind == "HEARTBEAT" and msg.type == mavlink.MAV_TYPE_GCS:
                continue
            with self._cond:
                self.latest[kind] = msg
                self.counts[kind] = self.counts.get(kind, 0) + 1
                if kind in self.kept:
                    self.kept[kind].append(msg)
                if kind == "STATUSTEXT":
                    self.texts.append(msg.text)
                elif kind == "GLOBAL_POSITION_INT":
                    self.positions.append((msg.lat * 1e-7, msg.lon * 1e-7, msg.relative_alt / 1e3))
                self._cond.notify_all()

    def wait(self, condition, timeout: float, what: str):
        """Wait until ``condition(monitor)`` is truthy; returns its value."""
        end = time.monotonic() + timeout
        with self._cond:
            while True:
                value = condition(self)
                if value:
                    return value
                left = end - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"{what}: not seen in {timeout:.0f} s; {self.summary()}")
                self._cond.wait(min(left, 0.5))

    def get(self, kind: str):
        return self.latest.get(kind)

    def armed(self) -> bool:
        hb = self.latest.get("HEARTBEAT")
        return bool(hb and hb.base_mode & self.mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)

    def custom_mode(self) -> int | None:
        hb = self.latest.get("HEARTBEAT")
        return None if hb is None else hb.custom_mode

    def boot_seconds(self) -> float:
        """The vehicle's own clock (time_boot_ms of its latest timed message)."""
        best = 0.0
        for kind in ("SYSTEM_TIME", "ATTITUDE", "GLOBAL_POSITION_INT", "GPS_RAW_INT"):
            msg = self.latest.get(kind)
            if msg is not None:
                ms = getattr(msg, "time_boot_ms", None)
                if ms is None and kind == "GPS_RAW_INT":
                    ms = msg.time_usec / 1000.0
                if ms:
                    best = max(best, ms / 1000.0)
        return best

    def summary(self) -> str:
        hb = self.latest.get("HEARTBEAT")
        pos = self.latest.get("GLOBAL_POSITION_INT")
        seen = ", ".join(f"{k} x{n}" for k, n in sorted(self.counts.items()))
        return (
            f"last HEARTBEAT {hb}; last GLOBAL_POSITION_INT {pos}; "
            f"last texts {self.texts[-5:]}; received: {seen or 'nothing'}"
        )

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self.conn.close()


def distance(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Horizontal metres between two nearby points."""
    r = 6378137.0
    north = math.radians(lat2 - lat1) * r
    east = math.radians(lon2 - lon1) * r * math.cos(math.radians(lat1))
    return math.hypot(north, east)


def offset(lat: float, lon: float, north: float, east: float) -> tuple[float, float]:
    """The point ``north``/``east`` metres from (lat, lon), rounded to MAVLink's 1e-7 deg."""
    r = 6378137.0
    dlat = math.degrees(north / r)
    dlon = math.degrees(east / (r * math.cos(math.radians(lat))))
    return round(lat + dlat, 7), round(lon + dlon, 7)
