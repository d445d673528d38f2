"""Lane methods, selectable by name. Each is a function

    method(image_bgr, camera, params, state) -> (LaneEstimate, new_state)

registered with `@register(name, Params)`, where Params is a frozen dataclass of the method's
parameters (defaults = the robust variant; `Params.published()` = the source's baseline).
`get(name)` returns a `LaneMethod` that binds parameters and carries the tracking state.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, fields, replace
from typing import Any, Callable

import numpy as np

from signlane.camera import Camera
from signlane.types import LaneEstimate

MethodFn = Callable[[np.ndarray, Camera, Any, Any], tuple[LaneEstimate, Any]]
_REGISTRY: dict[str, tuple[MethodFn, type]] = {}
# modules that register methods when imported (kept lazy so importing signlane stays light)
_MODULES = {"canny-scan": "canny_scan", "sliding-window": "sliding_window", "color-hough": "color_hough",
            "vector-spline": "vector_spline", "segnet": "segnet", "road-edges": "road_edges",
            "auto": "auto"}


def register(name: str, params_type: type) -> Callable[[MethodFn], MethodFn]:
    def deco(fn: MethodFn) -> MethodFn:
        _REGISTRY[name] = (fn, params_type)
        return fn
    return deco


def available() -> list[str]:
    """Names of the lane methods whose module is present."""
    out = []
    for name, mod in _MODULES.items():
        if importlib.util.find_spec(f"signlane.lanes.{mod}") is not None:
            out.append(name)
    return out


def _load(name: str) -> tuple[MethodFn, type]:
    if name not in _REGISTRY:
        if name not in _MODULES:
            raise ValueError(f"unknown lane method {name!r}; choose one of {', '.join(available())}")
        importlib.import_module(f"signlane.lanes.{_MODULES[name]}")
    return _REGISTRY[name]


def params_for(name: str, variant: str = "robust", **overrides) -> Any:
    """Parameters of a method: 'robust' (default) or 'published' (the source's baseline)."""
    _, ptype = _load(name)
    if variant == "published":
        p = ptype.published()
    elif variant == "robust":
        p = ptype()
    else:
        raise ValueError(f"variant must be 'robust' or 'published', not {variant!r}")
    known = {f.name for f in fields(ptype)}
    bad = set(overrides) - known
    if bad:
        raise ValueError(f"{name}: unknown parameter(s) {sorted(bad)}; known: {sorted(known)}")
    return replace(p, **overrides)


@dataclass
class LaneMethod:
    """A lane method bound to its parameters, carrying its tracking state between frames."""

    name: str
    params: Any
    camera: Camera | None = None
    state: Any = None

    def __call__(self, image_bgr: np.ndarray) -> LaneEstimate:
        fn, _ = _load(self.name)
        est, self.state = fn(image_bgr, self.camera, self.params, self.state)
        return est

    def settle(self) -> None:
        """Work the method put off until the frame's answer was out (a state with a `settle`
        method, e.g. auto's look for lane paint on a kerbed road); a no-op for the others. The
        next frame makes it anyway if it was not called."""
        settle = getattr(self.state, "settle", None)
        if settle is not None:
            self.state = settle(self.params)

    def reset(self) -> None:
        self.state = None


def get(name: str, camera: Camera | None = None, variant: str = "robust", **overrides) -> LaneMethod:
    return LaneMethod(name, params_for(name, variant, **overrides), camera)
