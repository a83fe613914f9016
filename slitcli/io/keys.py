"""Validation of parsed YAML mappings with one-line errors naming the file and key.

Used by the rig reader (:mod:`slitcli.rig`); every echoed value goes through
:func:`slitcli.io.yamlfile.brief` and every number through
:func:`slitcli.io.yamlfile.finite_float`.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from typing import Any

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.io.yamlfile import brief, finite_float

MAX_IMAGE_SIDE_PX = 16384
"""Largest image width or height a rig may give, pixels."""
MAX_IMAGE_PIXELS = 50_000_000
"""Largest image area a rig may give (width x height), pixels."""


class KeyReader:
    """Walks the YAML mapping and raises one-line errors naming file and key."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, problem: str, fix: str) -> SlitcliError:
        return SlitcliError(f"{self.source}: key '{key}' {problem}; {fix}")

    def mapping(self, value: Any, key: str, allowed: tuple[str, ...],
                required: tuple[str, ...]) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(key, "must be a mapping", f"give it the keys {', '.join(allowed)}")
        for k in value:
            if k not in allowed:
                close = difflib.get_close_matches(str(k), allowed, n=1)
                hint = f"did you mean '{close[0]}'?" if close else \
                    f"allowed keys are {', '.join(allowed)}"
                name = f"{key}.{k}" if key else str(k)
                raise SlitcliError(f"{self.source}: unknown key {brief(name)}; {hint}")
        for k in required:
            if k not in value:
                name = f"{key}.{k}" if key else k
                raise SlitcliError(f"{self.source}: missing key '{name}'; add it "
                                   "(see `slitcli rig init` for a complete example)")
        return value

    def number(self, m: Mapping[str, Any], key: str, prefix: str, *, default: float | None = None,
               low: float | None = None, high: float | None = None, low_open: bool = False,
               high_open: bool = False) -> float:
        name = f"{prefix}.{key}" if prefix else key
        if key not in m:
            if default is None:
                raise SlitcliError(f"{self.source}: missing key '{name}'; add it")
            return default
        v = finite_float(m[key])
        if v is None:
            raise self.fail(name, f"= {brief(m[key])} is not a finite number", "give a number")
        if low is not None and (v < low or (low_open and v == low)):
            sign = ">" if low_open else ">="
            raise self.fail(name, f"= {v:g} is out of range", f"it must be {sign} {low:g}")
        if high is not None and (v > high or (high_open and v == high)):
            sign = "<" if high_open else "<="
            raise self.fail(name, f"= {v:g} is out of range", f"it must be {sign} {high:g}")
        return v

    def vector(self, value: Any, key: str, shape: tuple[int, ...]) -> np.ndarray:
        try:
            a = np.asarray(value, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise self.fail(key, "is not a numeric matrix of finite numbers",
                            f"give a list of shape {shape}") from None
        # an open dimension is a list of distortion coefficients: OpenCV uses at most 14
        ok = a.ndim == len(shape) and all((s == -1 and 1 <= n <= 14) or s == n
                                          for s, n in zip(shape, a.shape, strict=False))
        if not ok or not np.all(np.isfinite(a)):
            want = "x".join("N" if s == -1 else str(s) for s in shape)
            raise self.fail(key, f"has shape {'x'.join(map(str, a.shape)) or 'scalar'}",
                            f"give a finite {want} list")
        return a


def image_size(r: KeyReader, size: Any, key: str) -> tuple[int, int]:
    """``[width, height]``: whole numbers of 8 to MAX_IMAGE_SIDE_PX pixels, bounded area."""
    if (not isinstance(size, list | tuple) or len(size) != 2
            or not all(isinstance(s, int) and not isinstance(s, bool) for s in size)
            or min(size) < 8 or max(size) > MAX_IMAGE_SIDE_PX
            or size[0] * size[1] > MAX_IMAGE_PIXELS):
        raise r.fail(key, f"= {brief(size)} is not a valid size",
                     f"give [width, height] as whole numbers of 8 to {MAX_IMAGE_SIDE_PX} pixels "
                     f"(at most {MAX_IMAGE_PIXELS} pixels in all)")
    return int(size[0]), int(size[1])
