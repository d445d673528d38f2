"""`signlane run`: the drive stack on a camera or a video, commands to an actuator.

    source (camera/video) -> DriveStack -> steering smoothing -> actuator
                                  \\-> Monitor (the web page, when on)

A camera reports no speed or wheel angle, so the stack is told the car does what it was last
asked (signlane.drive.stack.ToldCar). The car
is stopped safely (throttle 0, wheels straight) when no frame arrives for `frame_timeout_s`
(it drives on when frames come back), and always at the end: end of the video, Ctrl-C, a
failure. A frame the stack fails on gets the same safe command, and the loop goes on.
"""
from __future__ import annotations

import logging
import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from signlane.drive.signs import SignStageError
from signlane.drive.stack import ToldCar
from signlane.types import Command

log = logging.getLogger("signlane.run")
KEEP_LATENCIES = 20000  # frame -> command times kept for the summary (a camera runs for hours)


def safe_stop(why: str) -> Command:
    return Command(0.0, 0.0, f"stop: {why}")


class SteeringSmoother:
    """Exponential smoothing of steering: out += alpha * (new - out); alpha 1 = off. A camera's
    frame-to-frame noise otherwise reaches the servo as jitter."""

    def __init__(self, alpha: float = 1.0):
        if not 0 < alpha <= 1:
            raise ValueError(f"steering smoothing must be in (0, 1] (1 = off), not {alpha}")
        self.alpha = alpha
        self.value: float | None = None

    def step(self, steering: float) -> float:
        self.value = steering if self.value is None else self.value + self.alpha * (steering - self.value)
        return self.value

    def reset(self) -> None:
        self.value = None


@dataclass
class RunTotals:
    frames: int = 0  # frames driven
    failed: int = 0  # frames the stack failed on (answered with a safe stop)
    timeouts: int = 0  # times the source went quiet for longer than the timeout
    ended: str = ""
    step_ms: deque = field(default_factory=lambda: deque(maxlen=KEEP_LATENCIES))  # frame read -> command sent

    def summary(self, read: int) -> str:
        ms = np.asarray(self.step_ms) if self.step_ms else None
        lat = f"; frame -> command median {np.median(ms):.1f} ms, p99 {np.percentile(ms, 99):.1f} ms" \
            if ms is not None else ""
        return (f"{self.frames} frames driven of {read} read ({read - self.frames - self.failed} dropped while busy, "
                f"{self.failed} failed), {self.timeouts} camera timeouts{lat}; ended: {self.ended}")


def run_loop(source, stack, actuator, monitor=None, smoothing: float = 1.0, frame_timeout_s: float = 1.0,
             stop: threading.Event | None = None, max_speed: float | None = None) -> RunTotals:
    """Drive until the source ends or `stop` is set; the actuator's last command is a safe stop
    and it is closed. Ctrl-C (KeyboardInterrupt) stops the car the same way, then propagates."""
    stop = stop or threading.Event()
    smoother = SteeringSmoother(smoothing)
    car = ToldCar(stack.config.drive.max_speed if max_speed is None else max_speed)
    totals = RunTotals()
    quiet = False  # stopped for want of frames
    why = "the loop failed"
    try:
        while not stop.is_set():
            got = source.next(frame_timeout_s)
            if isinstance(got, str):  # the source ended
                why = got
                break
            if got is None:
                if not quiet:
                    totals.timeouts += 1
                    log.warning("no frame from %s for %.1f s: stopping the car until frames come back",
                                getattr(source, "name", "the source"), frame_timeout_s)
                    actuator.step(safe_stop(f"no frame for {frame_timeout_s:g} s"))
                    car.reset()
                    smoother.reset()
                    quiet = True
                continue
            if quiet:
                log.info("frames again: driving on")
                quiet = False
            try:
                perception, cmd = stack.drive(got.image, car.speed_mps, car.wheel_deg, got.t)
            except SignStageError as e:  # the car must not drive on without the signs it was asked to obey
                log.warning("%s; stopping the car on this frame", e)
                perception, cmd = None, safe_stop("sign stage failed")
                totals.failed += 1
            except Exception as e:  # a stack bug on one frame must not leave the car driving blind
                log.warning("the driver failed on frame %d: %s: %s; stopping the car on it", got.index,
                            type(e).__name__, e)
                perception, cmd = None, safe_stop("driver failed")
                totals.failed += 1
            if perception is not None:
                cmd = Command(smoother.step(cmd.steering), cmd.throttle, cmd.state)
                totals.frames += 1
            actuator.step(cmd)
            try:
                stack.answered()  # the command is out: the sign search of this frame may start
            except Exception as e:  # its work is about this frame; the next frame is driven as ever
                log.warning("the driver's work after frame %d failed: %s", got.index, e)
            ms = (time.perf_counter() - got.arrived) * 1e3
            totals.step_ms.append(ms)
            car.told(cmd)  # what a camera cannot measure
            if monitor is not None and perception is not None:
                monitor.publish(perception, cmd, car.speed_mps, ms, stack.confirmed, getattr(source, "name", ""))
        else:
            why = "stopped"
    except KeyboardInterrupt:
        why = "interrupted"
        raise
    finally:
        totals.ended = why
        try:
            actuator.step(safe_stop(why))
        finally:
            actuator.close()
            source.close()
    return totals
