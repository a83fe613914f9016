"""``slitcli report DETECT_OUT``: a self-contained look at one detection run.

Writes ``DETECT_OUT/report/`` (docs/report.md): ``heatmap.png`` (fused range per bearing
over time), ``birdseye.png`` (every frame's fused points from above), ``sources.png``
(the share of bins ranged by laser / stereo / neither), ``overlay.mp4`` (the left
images with stripe, obstacle mask and the fused ranges), a few overlay stills, colour
previews of one frame's disparity and distance when the run saved them, and
``index.html``, which embeds all images (base64) and opens from disk.

Every file is written under a temporary name and renamed when complete; a re-run
with the same inputs and settings skips the files already made (``.state.json``
records what they were made from), so a stopped report resumes.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from slitcli import __version__
from slitcli.errors import SlitcliError
from slitcli.io.atomic import write_bytes_atomic, write_png_atomic, write_text_atomic
from slitcli.report.overlay import OverlayParams, draw_overlay, write_video
from slitcli.report.preview import disparity_preview, distance_preview
from slitcli.report.run import (
    SOURCES,
    DetectRun,
    bag_stamps_ns,
    frame_times_s,
    left_images,
    load_run,
    resolve_source,
)

REPORT_DIR = "report"
STATE = ".state.json"
N_STILLS = 3


@dataclass(frozen=True, kw_only=True)
class ReportParams:
    """Settings of a report.

    Attributes
    ----------
    video : bool
        Make ``overlay.mp4`` (needs the run's input images).
    fps : float or None
        Video frame rate, frames/s; None: from the frame times (1 / median period,
        clipped to 1-30), else 5.
    period_s : float
        Frame period, seconds, for runs without frame times (the plots' time axis).
    overlay : OverlayParams
    dpi : int
        Resolution of the PNG figures.
    """

    video: bool = True
    fps: float | None = None
    period_s: float = 0.1
    overlay: OverlayParams = field(default_factory=OverlayParams)
    dpi: int = 110

    def __post_init__(self) -> None:
        if self.fps is not None and not (math.isfinite(self.fps) and 0.1 <= self.fps <= 120):
            raise SlitcliError(f"`fps` {self.fps} is out of range; give 0.1-120 frames/s",
                               param="fps")
        if not (math.isfinite(self.period_s) and self.period_s > 0):
            raise SlitcliError(f"`period_s` {self.period_s} must be a positive number of "
                               "seconds", param="period_s")
        if not 20 <= self.dpi <= 600:
            raise SlitcliError(f"`dpi` {self.dpi} is out of range; give 20-600", param="dpi")


@dataclass(frozen=True)
class ReportSummary:
    folder: Path
    frames: int
    share: dict[str, float]
    video_frames: int
    made: tuple[str, ...]
    skipped: tuple[str, ...]

    def line(self) -> str:
        share = ", ".join(f"{k} {100 * v:.1f} %" for k, v in self.share.items())
        video = f", video {self.video_frames} frames" if self.video_frames else ""
        resumed = f" ({len(self.skipped)} files already made)" if self.skipped else ""
        return (f"report: {self.frames} frames, bins ranged by {share}{video}{resumed} -> "
                f"{self.folder / 'index.html'}")


def time_axis(run: DetectRun, params: ReportParams, source: str | Path | None
              ) -> tuple[np.ndarray, bool, str]:
    """Frame times for the plots and the video (s), whether they are the run's own, and
    the axis label.

    A bag run takes its bag's stamps (exact; ``ranges.csv`` keeps 6 digits, too few for
    epoch stamps), counted from the first frame; a folder run its ``time_s``; a run
    without times ``frame index x period_s``.
    """
    if run.input_kind == "bag":
        stamps = bag_stamps_ns(run, source)
        if stamps is not None:
            return (stamps - stamps[0]) * 1e-9, True, "time since the first frame (s)"
    t, own = frame_times_s(run, params.period_s)
    return t, own, "time (s)" if own else f"time (s, frame index x {params.period_s:g} s)"


def video_fps(run: DetectRun, params: ReportParams, source: str | Path | None = None
              ) -> float:
    """Frames per second of the overlay video (:class:`ReportParams`)."""
    if params.fps is not None:
        return float(params.fps)
    t, own, _ = time_axis(run, params, source)
    if own and t.size > 1:
        return float(np.clip(1.0 / float(np.median(np.diff(t))), 1.0, 30.0))
    return 5.0


def _digest(paths: list[Path]) -> str:
    h = hashlib.sha256()
    for p in paths:
        h.update(str(p.name).encode())
        if p.is_file():
            st = p.stat()
            h.update(f"{st.st_size}:{st.st_mtime_ns}".encode())
    return h.hexdigest()


def _inputs_key(run: DetectRun, params: ReportParams, source: Path | None) -> str:
    files = [run.folder / "ranges.csv", run.folder / "laser.csv",
             run.folder / ".slitcli" / "detect" / "manifest.json"]
    masks = sorted((run.folder / "mask").glob("*.png")) if (run.folder / "mask").is_dir() \
        else []
    d = {"version": __version__, "params": asdict(params), "source": str(source),
         "files": _digest(files), "masks": _digest(masks)}
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()


class _State:
    """What is already in the report folder and what it was made from."""

    def __init__(self, folder: Path, key: str) -> None:
        self.path = folder / STATE
        self.key = key
        try:
            old = json.loads(self.path.read_text())
        except (OSError, json.JSONDecodeError, UnicodeDecodeError):
            old = {}
        self.done: set[str] = set(old.get("done", [])) if old.get("key") == key else set()
        self.done = {n for n in self.done if (folder / n).exists()}
        self.skipped: list[str] = []
        self.made: list[str] = []

    def need(self, name: str) -> bool:
        if name in self.done:
            self.skipped.append(name)
            return False
        return True

    def mark(self, name: str) -> None:
        self.done.add(name)
        self.made.append(name)
        write_text_atomic(self.path, json.dumps({"key": self.key, "done": sorted(self.done)}))


def run_report(run_dir: str | Path, *, params: ReportParams | None = None,
               source: str | Path | None = None,
               on_stage: Callable[[str], None] | None = None,
               on_total: Callable[[int], None] | None = None,
               on_frame: Callable[[], None] | None = None) -> ReportSummary:
    """Write ``run_dir/report/`` (module docstring; docs/report.md).

    Parameters
    ----------
    run_dir : path
        The output folder of ``slitcli detect``.
    params : ReportParams
    source : path, optional
        The run's input (sequence folder or bag) for the video; default: the path the
        manifest records.
    on_stage, on_total, on_frame : callables, optional
        Progress: a stage's name; the number of video frames; one video frame done.

    Raises
    ------
    SlitcliError
        Not a detect run; the input images cannot be found for the video.
    """
    p = ReportParams() if params is None else params
    run = load_run(run_dir)
    src = resolve_source(run, source) if p.video else None
    folder = run.folder / REPORT_DIR
    try:
        folder.mkdir(exist_ok=True)
    except OSError as e:
        raise SlitcliError(f"{folder}: cannot create the report folder ({e.strerror}); check "
                           "the permissions") from None
    state = _State(folder, _inputs_key(run, p, src))
    stage = on_stage if on_stage is not None else (lambda _s: None)
    times, own, label = time_axis(run, p, src)
    share = {name: float(np.mean(run.fused_source == k)) for k, name in enumerate(SOURCES)}

    figures = ("heatmap.png", "birdseye.png", "sources.png")
    if all(n in state.done for n in figures):
        state.skipped.extend(figures)
    else:
        stage("figures")
        _figures(run, folder, times, label, p, state)
    stage("previews")
    _previews(run, folder)
    video_frames = 0
    if p.video and src is not None and state.need("overlay.mp4"):
        stage("overlay video")
        if on_total is not None:
            on_total(run.n_frames)
        video_frames = write_video(folder / "overlay.mp4",
                                   _overlay_frames(run, src, times if own else
                                                   np.full(run.n_frames, np.nan), p, folder),
                                   fps=video_fps(run, p, src), on_frame=on_frame)
        state.mark("overlay.mp4")
    elif p.video:
        from slitcli.report.overlay import count_video_frames

        video_frames = count_video_frames(folder / "overlay.mp4")
    stage("index.html")
    write_text_atomic(folder / "index.html", render_html(run, folder, share, p,
                                                         times if own else None))
    state.mark("index.html")
    return ReportSummary(folder, run.n_frames, share, video_frames, tuple(state.made),
                         tuple(state.skipped))


def _figures(run: DetectRun, folder: Path, times: np.ndarray, label: str, p: ReportParams,
             state: _State) -> None:
    from matplotlib.figure import Figure

    from slitcli.figures import save
    from slitcli.report import plots

    vmax = max(run.rig.stereo.max_range_m, run.rig.laser.max_range_m)
    fig = Figure(figsize=(8, 4.2), layout="constrained")
    plots.draw_range_heatmap(fig.subplots(), times, run.bearing_deg, run.fused_range_m,
                             vmax_m=vmax, time_label=label)
    save(fig, folder / "heatmap.png", dpi=p.dpi)
    state.mark("heatmap.png")
    fig = Figure(figsize=(7, 6), layout="constrained")
    plots.draw_birdseye(fig.subplots(), run.bearing_deg, run.bin_deg, run.fused_range_m,
                        run.fused_source, times,
                        laser_band_m=(run.rig.laser.min_range_m, run.rig.laser.max_range_m),
                        max_range_m=vmax, time_label=label)
    save(fig, folder / "birdseye.png", dpi=p.dpi)
    state.mark("birdseye.png")
    fig = Figure(figsize=(8, 3.6), layout="constrained")
    plots.draw_source_share(fig.subplots(), times, run.fused_source, time_label=label)
    save(fig, folder / "sources.png", dpi=p.dpi)
    state.mark("sources.png")


def _middle_name(run: DetectRun, sub: str) -> str | None:
    names = run.frame_names()
    have = [n for n in names if (run.folder / sub / f"{n}.png").is_file()]
    return have[len(have) // 2] if have else None


def _previews(run: DetectRun, folder: Path) -> None:
    """Colour previews of the middle saved frame's disparity and distance images."""
    from slitcli.report.run import stereo_min_range_m

    min_m = stereo_min_range_m(run)
    max_disp = run.rig.focal_px * run.rig.baseline_m / min_m if min_m > 0 else 64.0
    for sub, decode, preview in (
            ("disparity", lambda a: a / 256.0,
             lambda v: disparity_preview(v, max_disparity_px=max_disp)),
            ("distance", lambda a: a / 1000.0,
             lambda v: distance_preview(v, max_range_m=run.rig.stereo.max_range_m))):
        name = _middle_name(run, sub)
        if name is None:
            continue
        raw = cv2.imread(str(run.folder / sub / f"{name}.png"), cv2.IMREAD_UNCHANGED)
        if raw is None or raw.dtype != np.uint16 or raw.ndim != 2:
            raise SlitcliError(f"{run.folder / sub / name}.png: not a 16-bit image "
                               "(docs/stereo.md); re-run detect with `save_images` on",
                               param="save_images")
        v = decode(raw.astype(np.float64))
        write_png_atomic(folder / f"preview_{sub}.png", preview(np.where(raw > 0, v, np.nan)))


def _stripes(run: DetectRun) -> dict[int, np.ndarray]:
    path = run.folder / "laser.csv"
    if not path.is_file():
        return {}
    try:
        t = pd.read_csv(path, usecols=["frame", "u_px", "v_px"])
    except (ValueError, pd.errors.ParserError, pd.errors.EmptyDataError):
        raise SlitcliError(f"{path}: not a laser table (docs/laser.md); re-run detect with "
                           "`save_images` on", param="save_images") from None
    uv = t[["u_px", "v_px"]].to_numpy(dtype=np.float64)
    f = t["frame"].to_numpy()
    order = np.argsort(f, kind="stable")
    keys, starts = np.unique(f[order], return_index=True)
    parts = np.split(uv[order], starts[1:])
    return {int(k): part for k, part in zip(keys, parts, strict=True)}


def still_frames(n: int) -> set[int]:
    """Positions (0..n-1) of the overlay stills: first, middle, last."""
    return {0, n // 2, n - 1} if n else set()


def _overlay_frames(run: DetectRun, src: Path, times: np.ndarray, p: ReportParams,
                    folder: Path) -> Iterator[np.ndarray]:
    stripes = _stripes(run)
    names = run.frame_names()
    position = {int(f): k for k, f in enumerate(run.frames)}
    stills = still_frames(run.n_frames)
    mask_dir = run.folder / "mask"
    for frame, left in left_images(run, src):
        k = position[frame]
        mask_path = mask_dir / f"{names[k]}.png"
        mask = cv2.imread(str(mask_path), cv2.IMREAD_GRAYSCALE) if mask_path.is_file() \
            else None
        img = draw_overlay(left, rig=_rectified(run), bearing_deg=run.bearing_deg,
                           bin_deg=run.bin_deg, fused_range_m=run.fused_range_m[k],
                           fused_source=run.fused_source[k], stripe_uv=stripes.get(frame),
                           mask=None if mask is None else mask > 0, time_s=float(times[k]),
                           frame=frame, params=p.overlay)
        if k in stills:
            write_jpeg_atomic(folder / f"overlay_{k:06d}.jpg", img)
        yield img


def write_jpeg_atomic(path: Path, img: np.ndarray, quality: int = 85) -> None:
    """JPEG for the overlay stills: a tenth of the PNG's size for a textured image."""
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise SlitcliError(f"{path}: OpenCV could not encode the image as JPEG")
    write_bytes_atomic(path, buf.tobytes())


def _rectified(run: DetectRun):
    from dataclasses import replace

    return replace(run.rig, raw=None)


def _img_tag(path: Path, alt: str) -> str:
    import base64
    import html

    data = base64.b64encode(path.read_bytes()).decode("ascii")
    mime = "image/jpeg" if path.suffix == ".jpg" else "image/png"
    return f'<img alt="{html.escape(alt)}" src="data:{mime};base64,{data}">'


def render_html(run: DetectRun, folder: Path, share: dict[str, float], p: ReportParams,
                times: np.ndarray | None) -> str:
    """The report page: every image inlined as base64, so the file opens from disk."""
    import html

    esc = html.escape
    dur = (f"{times[-1] - times[0]:.3f} s" if times is not None and times.size > 1 else "n/a")
    fused = run.fused_range_m
    nearest = float(np.nanmin(fused)) if np.isfinite(fused).any() else float("nan")
    rows = [("run", esc(str(run.folder))), ("input", esc(run.input_kind)),
            ("frames", str(run.n_frames)), ("duration", dur),
            ("bearing bins", f"{run.bearing_deg.size} x {run.bin_deg:g} deg, "
                             f"{run.bearing_deg[0]:g} to {run.bearing_deg[-1]:g} deg"),
            ("rig", esc(run.rig.name)),
            ("fusion", esc(str(run.manifest.get("params", {}).get("fusion_mode", "?")))),
            ("nearest fused range", f"{nearest:.3f} m" if math.isfinite(nearest) else "none")]
    rows += [(f"bins ranged by {k}" if k != "none" else "bins without a range (neither)",
              f"{100 * v:.1f} %") for k, v in share.items()]
    table = "\n".join(f"<tr><th>{a}</th><td>{b}</td></tr>" for a, b in rows)
    parts = [f"<h1>slitcli detection report</h1>\n<table>{table}</table>"]
    for name, title, text in (
            ("heatmap.png", "Range over time", "Fused range (Eq. 11) of every bearing bin "
             "over the run, metres; grey = no return."),
            ("birdseye.png", "Bird's-eye map", "The fused points of all frames in the "
             "sensor frame (x forward, y left), coloured by time; no odometry is used, so a "
             "moving robot's points smear along its path."),
            ("sources.png", "Which sensor ranged each bin", "Share of bearing bins whose "
             "fused range came from the laser, from stereo, or from neither (no return).")):
        if (folder / name).is_file():
            parts.append(f"<h2>{title}</h2><p>{text}</p>{_img_tag(folder / name, title)}")
    stills = sorted(folder.glob("overlay_*.jpg"))
    if p.video and (folder / "overlay.mp4").is_file():
        parts.append("<h2>Overlay video</h2><p><a href=\"overlay.mp4\">overlay.mp4</a> "
                     "(MPEG-4 Part 2; opens in VLC, mpv or any player with FFmpeg; browsers "
                     "may not play it): the left images with the detected laser stripe "
                     "(cyan), the stereo obstacle mask (magenta), and each bin's fused range "
                     "as an arc in the laser plane (yellow: laser, green: stereo) labelled "
                     "in metres. First, middle and last frame:</p>"
                     + "".join(_img_tag(s, s.stem) for s in stills))
    previews = [folder / f"preview_{s}.png" for s in ("disparity", "distance")]
    if any(pv.is_file() for pv in previews):
        parts.append("<h2>Disparity and distance (one frame)</h2><p>Colour previews of the "
                     "16-bit data files (docs/stereo.md); black = no valid value.</p>"
                     + "".join(_img_tag(pv, pv.stem) for pv in previews if pv.is_file()))
    style = ("body{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}"
             "img{max-width:100%;margin:.3em 0;border:1px solid #ddd}"
             "th{text-align:left;padding-right:1.5em}td,th{padding:.15em .5em}"
             "table{border-collapse:collapse}tr:nth-child(even){background:#f4f4f4}")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>slitcli report: {esc(run.folder.name)}</title><style>{style}</style>"
            "</head><body>\n" + "\n".join(parts) + f"\n<p><small>slitcli {__version__}"
            "</small></p></body></html>\n")


__all__ = ["ReportParams", "ReportSummary", "run_report", "still_frames", "video_fps"]
