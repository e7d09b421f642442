"""Command handles and the COMMAND_LONG tracker.

A :class:`Handle` is what every driver command returns (it satisfies
:class:`behaviors.ports.CommandHandle`). A :class:`CommandStep` is one MAVLink COMMAND_LONG
followed until its COMMAND_ACK: matched by command id (one command of a given id in flight at a
time, later ones wait in a queue), re-sent with ``confirmation`` incremented when no ACK comes,
optionally confirmed by what the autopilot reports afterwards (a mode change is only done when
HEARTBEAT.custom_mode shows it), and ended on a timeout in the injected clock's time. A refusing
ACK is final only after a short grace for the STATUSTEXT that explains it, which ArduPilot
sends just after the ACK ("Arm: Need Position Estimate").
A :class:`Procedure` chains steps (set mode, arm, take off) as a generator that yields the
sub-handle it waits for.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Generator
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from behaviors.ports import CommandStatus


def mav_cmd_name(command: int) -> str:
    """MAV_CMD number -> its name (``MAV_CMD_NAV_TAKEOFF``), or the number."""
    entry = mavlink.enums["MAV_CMD"].get(command)
    return entry.name if entry is not None else f"MAV_CMD {command}"


def mav_result_name(result: int) -> str:
    """MAV_RESULT number -> its name (``MAV_RESULT_DENIED``), or the number."""
    entry = mavlink.enums["MAV_RESULT"].get(result)
    return entry.name if entry is not None else f"MAV_RESULT {result}"


class Handle:
    """Progress of one vehicle command; satisfies :class:`behaviors.ports.CommandHandle`."""

    __slots__ = ("_name", "_status", "_reason", "created", "finished")

    def __init__(self, name: str, created: float) -> None:
        self._name = name
        self._status = CommandStatus.PENDING
        self._reason = ""
        self.created = created  # clock s
        self.finished: float | None = None  # clock s when it reached a final status

    @property
    def name(self) -> str:
        return self._name

    @property
    def status(self) -> CommandStatus:
        return self._status

    @property
    def reason(self) -> str:
        return self._reason

    @property
    def done(self) -> bool:
        return self._status.done

    def _set(self, status: CommandStatus, reason: str = "", now: float | None = None) -> None:
        if self._status.done:
            return
        self._status = status
        if reason:
            self._reason = reason
        if status.done:
            self.finished = now

    def __repr__(self) -> str:
        extra = f", reason={self._reason!r}" if self._reason else ""
        return f"<{type(self).__name__} {self._name} {self._status.value}{extra}>"


def finished_handle(name: str, now: float, status: CommandStatus, reason: str = "") -> Handle:
    """A handle that is already over (accepted at once, or refused before sending)."""
    handle = Handle(name, now)
    handle._set(status, reason, now)
    return handle


class CommandStep(Handle):
    """One COMMAND_LONG followed until acknowledged (and confirmed, if asked).

    Attributes:
        command: MAV_CMD number.
        params: the seven float parameters.
        confirm: predicate that is true once the autopilot reports the command's effect (e.g.
            the new mode in HEARTBEAT); with it, an accepting ACK only moves the handle to
            IN_PROGRESS, and the effect alone (even without an ACK) makes it ACCEPTED.
        unconfirmed_reason: says what the autopilot shows instead, for the denial message.
        denied_reason: gives extra words for a denial (e.g. the latest PreArm text), used
            when no STATUSTEXT arrives within the grace after the refusing ACK.
    """

    __slots__ = (
        "command",
        "params",
        "confirm",
        "unconfirmed_reason",
        "denied_reason",
        "attempts",
        "last_sent",
        "acked",
        "in_progress_since",
        "refusal",
        "refused_at",
    )

    def __init__(
        self,
        name: str,
        created: float,
        command: int,
        params: tuple[float, ...],
        *,
        confirm: Callable[[], bool] | None = None,
        unconfirmed_reason: Callable[[], str] | None = None,
        denied_reason: Callable[[], str] | None = None,
    ) -> None:
        super().__init__(name, created)
        self.command = command
        self.params = tuple(float(p) for p in params) + (0.0,) * (7 - len(params))
        self.confirm = confirm
        self.unconfirmed_reason = unconfirmed_reason
        self.denied_reason = denied_reason
        self.attempts = 0  # COMMAND_LONGs sent so far; confirmation = attempts - 1
        self.last_sent: float | None = None
        self.acked = False  # an accepting ACK arrived, now waiting for confirmation
        self.in_progress_since: float | None = None
        self.refusal = ""  # "MAV_CMD_...: MAV_RESULT_..." of a refusing ACK awaiting its text
        self.refused_at: float | None = None


@dataclass
class TrackerSettings:
    """Timing of the COMMAND_LONG tracker, in clock seconds."""

    ack_timeout: float = 1.0  # wait this long for an ACK before re-sending
    attempts: int = 4  # COMMAND_LONGs sent at most (the first + re-sends)
    in_progress_timeout: float = 30.0  # after MAV_RESULT_IN_PROGRESS, wait this long
    confirm_timeout: float = 3.0  # after an accepting ACK, wait this long for the effect
    refusal_text_grace: float = 0.5  # after a refusing ACK, wait this long for its STATUSTEXT


class CommandTracker:
    """Sends COMMAND_LONGs, matches COMMAND_ACKs by command id, re-sends and times out.

    ``send(step)`` is called to put a COMMAND_LONG for ``step`` on the link, with
    ``confirmation = step.attempts - 1`` (the tracker increments ``attempts`` first).
    """

    def __init__(self, send: Callable[[CommandStep], None], settings: TrackerSettings) -> None:
        self._send = send
        self.settings = settings
        self._in_flight: dict[int, CommandStep] = {}
        self._waiting: deque[CommandStep] = deque()
        self.acks_unmatched = 0

    def __len__(self) -> int:
        return len(self._in_flight) + len(self._waiting)

    def submit(self, step: CommandStep, now: float) -> CommandStep:
        """Queue ``step``; it is sent at once if no command of its id is in flight."""
        self._waiting.append(step)
        self._start_waiting(now)
        return step

    def _transmit(self, step: CommandStep, now: float) -> None:
        step.attempts += 1
        step.last_sent = now
        self._send(step)

    def _start_waiting(self, now: float) -> None:
        if not self._waiting:
            return
        kept: deque[CommandStep] = deque()
        while self._waiting:
            step = self._waiting.popleft()
            if step.done:
                continue
            if step.confirm is not None and step.confirm():
                step._set(CommandStatus.ACCEPTED, now=now)  # already so: nothing to send
                continue
            if step.command in self._in_flight:
                kept.append(step)
                continue
            self._in_flight[step.command] = step
            self._transmit(step, now)
        self._waiting = kept

    def on_ack(self, command: int, result: int, now: float) -> None:
        """Apply a COMMAND_ACK addressed to us."""
        step = self._in_flight.get(command)
        if step is None:
            self.acks_unmatched += 1
            return
        if result == mavlink.MAV_RESULT_ACCEPTED:
            if step.confirm is None or step.confirm():
                step._set(CommandStatus.ACCEPTED, now=now)
            else:
                step.acked = True
                step.last_sent = now  # the confirmation clock starts at the ACK
                step._set(CommandStatus.IN_PROGRESS)
        elif result == mavlink.MAV_RESULT_IN_PROGRESS:
            step.in_progress_since = now
            step._set(CommandStatus.IN_PROGRESS)
        elif step.refused_at is None:
            step.refusal = f"{mav_cmd_name(command)}: {mav_result_name(result)}"
            step.refused_at = now
            if self.settings.refusal_text_grace <= 0:
                self._refuse(step, None, now)
        self._retire(now)

    def on_text(self, text: str, now: float) -> None:
        """A STATUSTEXT worth reporting arrived: it explains the refusals awaiting one."""
        for step in self._in_flight.values():
            if step.refused_at is not None and not step.done:
                self._refuse(step, text, now)
        self._retire(now)

    @staticmethod
    def _refuse(step: CommandStep, text: str | None, now: float) -> None:
        if text is None and step.denied_reason is not None:
            text = step.denied_reason()
        reason = f"{text} ({step.refusal})" if text else step.refusal
        step._set(CommandStatus.DENIED, reason, now)

    def update(self, now: float) -> None:
        """Confirm, re-send and time out the commands in flight; start queued ones."""
        if not self._in_flight and not self._waiting:
            return  # nothing to follow (most ticks)
        s = self.settings
        for step in list(self._in_flight.values()):
            if step.done:
                continue
            if step.refused_at is not None:
                if now - step.refused_at >= s.refusal_text_grace - 1e-6:  # float tick sums
                    self._refuse(step, None, now)
                continue
            if step.confirm is not None and step.confirm():
                step._set(CommandStatus.ACCEPTED, now=now)
                continue
            assert step.last_sent is not None
            waited = now - step.last_sent
            if step.acked:
                if waited >= s.confirm_timeout:
                    shown = step.unconfirmed_reason() if step.unconfirmed_reason else ""
                    step._set(
                        CommandStatus.DENIED,
                        f"{mav_cmd_name(step.command)} acknowledged but not applied{shown}",
                        now,
                    )
            elif step.in_progress_since is not None:
                if now - step.in_progress_since >= s.in_progress_timeout:
                    step._set(
                        CommandStatus.TIMED_OUT,
                        f"{mav_cmd_name(step.command)} still in progress after "
                        f"{s.in_progress_timeout:g} s",
                        now,
                    )
            elif waited >= s.ack_timeout:
                if step.attempts >= s.attempts:
                    step._set(
                        CommandStatus.TIMED_OUT,
                        f"no COMMAND_ACK for {mav_cmd_name(step.command)} after "
                        f"{step.attempts} attempts",
                        now,
                    )
                else:
                    self._transmit(step, now)
        self._retire(now)

    def fail_all(self, status: CommandStatus, reason: str, now: float) -> None:
        """End every queued and in-flight command (e.g. the link is lost)."""
        for step in [*self._in_flight.values(), *self._waiting]:
            step._set(status, reason, now)
        self._in_flight.clear()
        self._waiting.clear()

    def _retire(self, now: float) -> None:
        for command in [c for c, step in self._in_flight.items() if step.done]:
            del self._in_flight[command]
        self._start_waiting(now)


class Wait(Handle):
    """A step of a procedure that waits for a condition (e.g. setpoints already streaming)."""

    __slots__ = ("predicate", "deadline", "timeout_reason")

    def __init__(
        self,
        name: str,
        created: float,
        predicate: Callable[[], bool],
        timeout: float,
        timeout_reason: str,
    ) -> None:
        super().__init__(name, created)
        self.predicate = predicate
        self.deadline = created + timeout
        self.timeout_reason = timeout_reason

    def update(self, now: float) -> None:
        if self.done:
            return
        if self.predicate():
            self._set(CommandStatus.ACCEPTED, now=now)
        elif now >= self.deadline:
            self._set(CommandStatus.TIMED_OUT, self.timeout_reason, now)


StepGenerator = Generator[Handle | None, None, None]


class Procedure(Handle):
    """A command made of steps: a generator yielding the handle of each step in turn.

    The procedure is ACCEPTED when the generator finishes, and ends with the status and reason
    of the first step that does not succeed. Yielding ``None`` ends the procedure at once.
    """

    __slots__ = ("_steps", "current", "on_accept", "kind")

    def __init__(
        self,
        name: str,
        created: float,
        steps: StepGenerator,
        on_accept: Callable[[], None] | None = None,
        kind: str = "",
    ) -> None:
        super().__init__(name, created)
        self._steps = steps
        self.current: Handle | None = None
        self.on_accept = on_accept
        self.kind = kind  # e.g. "guided": follows a setpoint stream that others may stop

    def advance(self, now: float) -> None:
        """Move on while the current step has succeeded; never waits."""
        while not self.done:
            if self.current is not None:
                if isinstance(self.current, Wait):
                    self.current.update(now)
                status = self.current.status
                if not status.done:
                    if status is CommandStatus.IN_PROGRESS:
                        self._set(CommandStatus.IN_PROGRESS)
                    return
                if status is not CommandStatus.ACCEPTED:
                    self._set(status, f"{self.current.name}: {self.current.reason}", now)
                    self._steps.close()
                    return
            try:
                self.current = next(self._steps)
            except StopIteration:
                self._set(CommandStatus.ACCEPTED, now=now)
                if self.on_accept is not None:
                    self.on_accept()
                return
            if self.current is None:
                self._set(CommandStatus.ACCEPTED, now=now)
                self._steps.close()
                return

    def cancel(self, reason: str, now: float, status: CommandStatus = CommandStatus.DENIED) -> None:
        """End the procedure (superseded by another command, or the link is lost)."""
        if self.current is not None and not self.current.done:
            self.current._set(status, reason, now)
        self._set(status, reason, now)
        self._steps.close()
