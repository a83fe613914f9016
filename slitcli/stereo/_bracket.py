"""The SGM bracket test (slitcli.stereo.sgm; compiled: slitcli/stereo/_c/bracket.pyx,
where the rule is documented)."""

from __future__ import annotations

import numpy as np

from slitcli.stereo._c import bracket as _c


def bracket_rows(disp: np.ndarray, reason: np.ndarray, code_valid: int, weak: np.ndarray,
                 reach: int, tol: float, span: float, keep: np.ndarray) -> None:
    """Set ``keep`` (H, W) bool where a pixel whose code is marked in ``weak`` ((256,)
    bool per code) is bracketed along its row or its column by pixels of code
    ``code_valid`` within ``reach`` px: ``min(d_a, d_b) - tol <= d <= max(d_a, d_b) +
    tol`` with ``|d_a - d_b| <= span`` (px).

    ``disp`` (H, W) float32, px; ``reason`` (H, W) uint8 codes. Only ``keep`` is written
    (False at the other non-valid pixels, valid pixels untouched)."""
    _c.bracket_rows(disp, reason, int(code_valid), weak.view(np.uint8), int(reach),
                    np.float32(tol), np.float32(span), keep.view(np.uint8))


__all__ = ["bracket_rows"]
