"""One simulator run, start to finish: a track, the simulator, a driver (in-process, via a drive
server this process starts, or an external server), an optional annotated video, and the report
files (report JSON, top-down path PNG)."""
from __future__ import annotations

import contextlib
import logging
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

from signlane.config import Config
from signlane.draw import draw_boxes, draw_hud, draw_lane, write_image
from signlane.fileio import atomic_write_json
from signlane.sim.simulator import SimConfig, Simulator, run_client, run_inprocess
from signlane.video_out import VideoOut
from signlane.world.route import Route
from signlane.world.topdown import draw_topdown
from signlane.world.track import Track

log = logging.getLogger(__name__)


def annotate_drive(image: np.ndarray, perception, command, speed: float, t: float) -> np.ndarray:
    """A copy of a driven frame with what the driver saw and did: lanes, signs, state, command."""
    out = image.copy()
    if perception is not None:
        draw_lane(out, perception.lane.left, perception.lane.right)
        draw_boxes(out, [(d.label, d.score, d.box) for d in perception.signs])
    draw_hud(out, [f"t {t:6.1f} s  speed {speed:4.1f} m/s", f"state {command.state}",
                   f"steering {command.steering:+.2f}  throttle {command.throttle:.2f}"])
    return out


class SeenByDriver:
    """Builds the drive server's drivers and keeps the newest frame's (perception, command), so a
    video of a run through the server (`sim --with-driver --video`) shows what the driver saw,
    as the in-process demo's does: neither is on the wire."""

    def __init__(self, config: Config, sync_signs: bool):
        self.config, self.sync_signs = config, sync_signs
        self.latest = (None, None)  # set on a server thread, read by the simulator's: one assignment

    def __call__(self) -> "_Tapped":
        from signlane.sim.driver import Driver
        return _Tapped(Driver(self.config, sync_signs=self.sync_signs), self)


class _Tapped:
    """A Driver whose every step is also handed to its SeenByDriver."""

    def __init__(self, driver, seen: SeenByDriver):
        self.driver, self.seen = driver, seen

    def step(self, telemetry, now: float | None = None):
        self.seen.latest = result = self.driver.step(telemetry, now)
        return result

    def close(self) -> None:
        self.driver.close()

    def __getattr__(self, name):
        return getattr(self.driver, name)


def _loop_length(track: Track) -> float | None:
    """Metres of the start's loop (the route the driver's turns may still change), or None
    where the road from the start ends before it closes."""
    try:
        return float(Route.loop(track).length)
    except RuntimeError:
        return None


def drive_meta(track: Track, sim_config: SimConfig, noise=None, every: int = 1, student: dict | None = None) -> dict:
    """What a recording's manifest says of the drive: track, style, looks, frame rate, noise, and
    the student that steered it (DAgger), if one did."""
    from dataclasses import asdict
    return {"track": track.name, "source": getattr(track, "source", ""), "style": track.style.kind,
            "looks": {"random": bool(sim_config.random_looks), "seed": int(sim_config.looks_seed)},
            "effects": sim_config.effects, "fps": sim_config.fps, "size": [sim_config.width, sim_config.height],
            "record_every": int(every), "perturb": asdict(noise.p) if noise is not None else None,
            "student": student}


def _inprocess(sim, driver, progress, record, config, meta, noise, every, takeover) -> dict:
    """run_inprocess, recording the teacher's drive where asked (the student's, when the driver
    has a pilot: signlane/sim/teacher.py); the report counts the frames the teacher took over."""
    if record is None:
        return run_inprocess(sim, driver, progress)
    from signlane.sim.drive_record import Recorder
    from signlane.sim.teacher import TeacherRecorder
    recorder = Recorder(record, config, meta)
    try:
        teacher = TeacherRecorder(driver, recorder, noise, every, takeover)
        rep = run_inprocess(sim, teacher, progress)
        if teacher.takeover is not None:
            rep["takeover_share"] = round(teacher.takeover.taken / max(teacher.takeover.frames, 1), 4)
        return rep
    finally:
        recorder.close()


def run_session(track: Track, sim_config: SimConfig, out: Path | None, config: Config | None = None,
                url: str | None = None, lockstep: bool = True, with_driver: bool = False,
                video: bool = False, show_progress: bool = True, server_options=None,
                record: Path | None = None, noise=None, record_every: int = 1, takeover=None) -> dict:
    """Drive one run; returns the report (also written to out/report.json with out/path.png).
    server_options: the in-process drive server's (with_driver; default a free port on 127.0.0.1
    with the monitor on); its sync_signs follows `lockstep`.
    record: a folder for the drive recording (signlane/sim/drive_record.py), made by the
    in-process driver (every `record_every`-th frame, the applied steering perturbed by `noise`,
    a signlane.sim.teacher.SteeringNoise) or by the drive server (with_driver). With a pilot in
    `config` the in-process recording is a DAgger drive: the pilot steers where `takeover` (a
    signlane.sim.teacher.Takeover; default margins when None) lets it, the teacher labels."""
    if record is not None and url is not None:
        raise ValueError("--record: a remote drive server records with its own `signlane drive --record`")
    if noise is not None and (with_driver or url is not None):
        raise ValueError("--perturb needs the in-process driver (no --with-driver, no --url)")
    sim = Simulator(track, sim_config)
    config = config or Config()
    # the bar counts metres along the start's loop (a whole lap of laps would sit at 0 for minutes)
    lap_m = _loop_length(track)
    total = round(sim_config.laps * lap_m) if lap_m else sim_config.laps
    bar = tqdm(total=total, desc=f"lap 1/{sim_config.laps}", unit="m" if lap_m else "lap", disable=not show_progress)
    writer = None
    if video and out is not None:
        out.mkdir(parents=True, exist_ok=True)
        # an uncapped run has no frame rate of its own: play it at 30 frames/s
        writer = VideoOut(out / "drive.mp4", sim_config.fps or 30.0, (sim_config.width, sim_config.height))

    seen = SeenByDriver(config, lockstep) if with_driver and writer is not None else None

    def progress(s, cmd, perception):
        laps = s.course.laps
        if lap_m:  # the odometer, held short of the end until the lap is really counted
            bar.n = total if laps >= sim_config.laps else min(round(s.vehicle.odometer_m), total - 1)
        else:
            bar.n = laps
        if s.frame % 20 == 0:
            bar.set_description_str(f"lap {min(laps + 1, sim_config.laps)}/{sim_config.laps}", refresh=False)
        bar.set_postfix_str(f"t={s.t:.0f}s off={s.score.offroad_events}", refresh=s.frame % 20 == 0)
        if writer is not None:
            if seen is not None and seen.latest[0] is not None:
                perception, cmd = seen.latest
            writer.write(annotate_drive(s.last_image, perception, cmd, s.vehicle.speed, s.t))

    t0 = time.perf_counter()
    # log lines (the drive server's) go above the bar instead of through it
    with logging_redirect_tqdm() if show_progress else contextlib.nullcontext():
        try:
            if url is None and not with_driver:
                from signlane.sim.driver import Driver
                with Driver(config, sync_signs=lockstep) as driver:
                    student = None
                    if driver.pilot is not None:
                        from dataclasses import asdict
                        from signlane.sim.teacher import TakeoverParams
                        student = {"model": config.pilot.model, "junctions": config.pilot.junctions,
                                   "lost_speed": config.pilot.lost_speed,
                                   "takeover": asdict(takeover.p if takeover is not None else TakeoverParams())}
                    meta = drive_meta(track, sim_config, noise, record_every, student)
                    rep = _inprocess(sim, driver, progress, record, config, meta, noise, record_every, takeover)
                    rep["decisions"] = driver.behaviour.decisions  # what the driver saw at each junction
            elif with_driver:
                from dataclasses import replace
                from signlane.sim.server import DriveServer, ServerOptions
                options = replace(server_options or ServerOptions(port=0), sync_signs=lockstep)
                options = replace(options, record=record) if record is not None else options
                srv = DriveServer(config, options, driver_factory=seen)
                with srv:
                    if seen is not None:
                        seen.latest = (None, None)  # the server's start-up probe drove a blank frame
                    rep = run_client(sim, srv.url, lockstep, progress)
                # the server's own split of its time: decoding, the driver, and frame in -> answer out
                rep["server_latency_ms"] = {k: v for k, v in (srv.totals or {}).items() if "_ms_" in k}
            else:
                rep = run_client(sim, url, lockstep, progress)
        except BaseException:
            if writer is not None:  # a failed run leaves no video (and its error is the run's, not the video's)
                writer.discard()
                writer = None
            raise
        finally:
            bar.close()
            if writer is not None:
                writer.close()
    rep["fps"] = round(sim.frame / max(time.perf_counter() - t0, 1e-9), 2)
    rep["map"] = track.name
    rep["mode"] = "lockstep" if lockstep else \
        (f"real time {sim_config.fps:g} Hz" if sim_config.fps > 0 else "real time uncapped")
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(out / "report.json", rep)
        write_image(out / "path.png", draw_topdown(sim.renderer.scene, path_xy=np.array(sim.path),
                                                   marks=rep["offroad_xy_m"], marks_label="off the road",
                                                   legend="driven path"))
    return rep
