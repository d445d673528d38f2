"""The drive's score: laps, autonomy, off-road events, cross-track error, rule compliance, rates."""
from __future__ import annotations

import numpy as np

from signlane.tables import pairs

INTERVENTION_S = 6.0  # PilotNet: each intervention costs 6 seconds of autonomy


class Score:
    """`offroad_m`: the cross-track error at which the car is off its road (RoadStyle.offroad_m:
    on VIA's kerbed road its centre over the kerb; on a painted road 0.5 m beyond its lane)."""

    def __init__(self, lane_width_m: float, offroad_m: float):
        self.lane_w = lane_width_m
        self.offroad_m = offroad_m
        self.cte: list[float] = []
        self.speeds: list[float] = []
        self.latency: list[float] = []
        self.offroad_events = 0
        self.offroad: list[tuple[float, float, float]] = []  # (t, x, y) of each: when, and where on the map

    def frame(self, t: float, cte_m: float, speed: float, latency_ms: float | None,
              xy: tuple[float, float]) -> bool:
        """Record one frame (the car at world metres `xy`); True when the car has just gone off
        its lane (an intervention)."""
        self.cte.append(abs(cte_m) / self.lane_w)
        self.speeds.append(speed)
        if latency_ms is not None:
            self.latency.append(latency_ms)
        if abs(cte_m) > self.offroad_m:
            self.offroad_events += 1
            self.offroad.append((round(t, 2), round(float(xy[0]), 2), round(float(xy[1]), 2)))
            return True
        return False

    def report(self, course, distance_m: float, time_s: float) -> dict:
        turns = [j for j in course.log.junctions if j["sign"] is not None or j.get("dead_end")]
        stops = course.log.stops
        lat = np.array(self.latency) if self.latency else np.zeros(1)
        autonomy = 100.0 * max(0.0, 1.0 - self.offroad_events * INTERVENTION_S / max(time_s, 1e-9))
        return {"laps": int(course.laps), "autonomy": round(autonomy, 2), "offroad_events": self.offroad_events,
                "cte_mean": round(float(np.mean(self.cte)) if self.cte else 0.0, 4),
                "cte_max": round(float(np.max(self.cte)) if self.cte else 0.0, 4),
                "stops": {"required": len(stops), "complied": sum(s["complied"] for s in stops)},
                "turns": {"required": len(turns), "complied": sum(bool(j["complied"]) for j in turns)},
                "distance_m": round(distance_m, 2), "time_s": round(time_s, 2),
                "mean_speed": round(distance_m / max(time_s, 1e-9), 3),
                "fps": 0.0, "latency_ms": {"median": round(float(np.median(lat)), 2),
                                           "p99": round(float(np.percentile(lat, 99)), 2)},
                "dead_ends_taken": sum(bool(j.get("dead_end")) for j in course.log.junctions),
                "junctions": course.log.junctions, "stop_log": stops, "offroad_at_s": [t for t, _, _ in self.offroad],
                "offroad_xy_m": [[x, y] for _, x, y in self.offroad]}


def format_report(rep: dict) -> str:
    rows = [("laps", rep["laps"]), ("autonomy %", f"{rep['autonomy']:.1f}"), ("off-road events", rep["offroad_events"]),
            ("cross-track mean / max (lane widths)", f"{rep['cte_mean']:.3f} / {rep['cte_max']:.3f}"),
            ("stops complied / required", f"{rep['stops']['complied']} / {rep['stops']['required']}"),
            ("turns complied / required", f"{rep['turns']['complied']} / {rep['turns']['required']}"),
            ("distance m / time s", f"{rep['distance_m']:.0f} / {rep['time_s']:.1f}"),
            ("mean speed m/s", f"{rep['mean_speed']:.2f}"), ("frames/s (wall)", f"{rep['fps']:.1f}"),
            ("server latency median / p99 ms", f"{rep['latency_ms']['median']:.1f} / {rep['latency_ms']['p99']:.1f}")]
    split = rep.get("server_latency_ms") or {}
    for k in ("decode", "perceive", "answer"):  # the drive server's own split (sim --with-driver)
        if f"{k}_ms_median" in split:
            rows.append((f"  in the server: {k} median / p99 ms",
                         f"{split[f'{k}_ms_median']:.1f} / {split[f'{k}_ms_p99']:.1f}"))
    return pairs(rows)
