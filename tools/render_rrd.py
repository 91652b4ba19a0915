"""Render the Rerun files a user opens to PNG, in the real Rerun viewer: the user guide's images.

What it renders (``docs/rerun/`` by default):

* ``session.png`` — ``session001.rrd`` of the bundled pipeline
  (``pipelines/table2-repeatability.toml``), as it opens; ``session_clipped.png`` —
  its ``session004.rrd``, whose fast first turns clipped 18 % of the samples at ±4 g;
* ``batch.png``, ``batch_spin.png`` and ``batch_sessions.png`` — its
  ``batch.rrd``: the group's tab (as it opens), the group's spin tab and the
  sessions tab;
* ``closed_loop.png`` and ``closed_loop_calibration.png`` — a simulated
  session with an undeclared wheel imbalance (0.15 rad/s², the size of
  ``tests/test_closed_loop.py``), run through ``wheelcal diagnose --rrd``: the
  closed-loop tab (before/after) and the calibration tab.

The pipeline and the diagnosis run first, with the current interpreter and
this tree's ``wheelcal`` (``--out`` holds their outputs; existing recordings
are reused).  The viewer is Rerun's web viewer from the installed rerun-sdk
(``rerun.serve_web_viewer``), loading each file over HTTP as a user opening
it would, in headless Chromium (Debian's ``chromium`` package) driven by
Playwright (``pip install playwright``; never ``playwright install``: the
system browser is used), with WebGL (``?renderer=webgl``: a software
renderer, no GPU needed).  The viewer draws on one canvas; a tab is opened by
clicking its title, found in the tab bar's pixels, and **checked by what the viewer
then shows**, never by "the pixels changed" (the mouse over a title highlights it,
which a pixel difference takes for a switch): after the click the mouse leaves the
tab bar, and the tab counts as open only when the viewer marks that title as the
selected tab (its blue pill, :func:`selected_tab`) and the views below the tab bar
differ from the tab it opened on (:func:`views_changed`).  A shot whose tab cannot be
verified is an error, not an image.

    python tools/render_rrd.py [--out out/render] [--docs docs/rerun]
        [--chromium /usr/bin/chromium] [--size 1920x1080]

Look at every image after running it.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import functools
import http.server
import io
import itertools
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PIPELINE = ROOT / "pipelines" / "table2-repeatability.toml"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
#: Seconds for the viewer to load a file and draw it (software WebGL is slow).
LOAD_S = 10.0
#: Height of the viewer's top bar and of a tab bar, px (Rerun 0.41 at 1× zoom).
TOP_BAR_PX = 36
TAB_BAR_PX = 24


@dataclasses.dataclass(frozen=True)
class Shot:
    """One PNG: a file, which tab (0 = as it opens; k = the k-th tab title clicked)."""

    file: Path
    png: str
    tab: int | None = None


def wheelcal(*args: str, cwd: Path = ROOT) -> None:
    """Run the ``wheelcal`` command of this interpreter in ``cwd`` (exit status checked)."""
    subprocess.run([sys.executable, "-m", "wheelcal.cli.main", *args], check=True, cwd=cwd)


def imbalance_recording(path: Path) -> None:
    """A full session (rest, push, spin, brake, rest) of Table I with an undeclared imbalance."""
    from wheelcal.io import write_recording
    from wheelcal.simulate import table1
    from wheelcal.simulate.motion import ImbalancedSpin
    from wheelcal.simulate.session import simulate_session

    scenario = table1()
    eps_radps2, phase_rad = 0.15, 0.7
    motion = ImbalancedSpin(
        scenario.truth.spin, eps_radps2 * np.cos(phase_rad), eps_radps2 * np.sin(phase_rad)
    )
    scenario = dataclasses.replace(scenario, motion=motion)
    start_unix_ns = 1_710_241_200_000_000_000  # 2024-03-12 11:00:00 UTC
    recording = simulate_session(
        scenario, np.random.default_rng(31), epoch_unix_ns=start_unix_ns, source=str(path)
    ).recording
    write_recording(recording, path)


def make_files(out: Path) -> dict[str, Path]:
    """The bundled pipeline's outputs and a diagnosed imbalance session; their .rrd paths."""
    wheelcal("batch", str(PIPELINE))
    pipeline_out = ROOT / "out" / "table2-repeatability"
    out.mkdir(parents=True, exist_ok=True)
    mcap = out / "imbalance.mcap"
    if not mcap.exists():
        imbalance_recording(mcap)
    # run where the file is: the views name it as a user would see it, not by this machine's path
    wheelcal("diagnose", mcap.name, "--out", ".", "--rrd", cwd=out.resolve())
    return {
        "session": pipeline_out / "session001.rrd",
        "clipped": pipeline_out / "session004.rrd",
        "batch": pipeline_out / "batch.rrd",
        "closed_loop": out / "imbalance.rrd",
    }


class _Handler(http.server.SimpleHTTPRequestHandler):
    """Serves the files with the CORS header the web viewer (another port) needs."""

    def end_headers(self) -> None:
        self.send_header("Access-Control-Allow-Origin", "*")
        super().end_headers()

    def log_message(self, *args) -> None:  # quiet
        pass


@contextlib.contextmanager
def file_server(root: Path):
    """An HTTP server of ``root`` on a free local port; yields its base URL."""
    handler = functools.partial(_Handler, directory=str(root))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()


def tab_centres(png: bytes, width: int) -> list[int]:
    """The x of each tab title in the viewport's tab bar (runs of ink > 14 px apart)."""
    from PIL import Image

    image = np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=float)
    strip = image[TOP_BAR_PX + 4 : TOP_BAR_PX + TAB_BAR_PX - 4, : width - 40]
    ink = np.flatnonzero((strip.max(axis=0) - strip.min(axis=0)) > 60)
    if ink.size == 0:
        return []
    runs, start = [], ink[0]
    for a, b in itertools.pairwise(ink):
        if b - a > 14:
            runs.append((start, a))
            start = b
    runs.append((start, ink[-1]))
    return [int((a + b) / 2) for a, b in runs]


def small_png(png: bytes) -> bytes:
    """The screenshot with a 128-colour palette (a few hundred kB less, same look)."""
    from PIL import Image

    image = Image.open(io.BytesIO(png)).convert("RGB")
    buffer = io.BytesIO()
    image.quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(
        buffer, format="PNG", optimize=True
    )
    return buffer.getvalue()


def settle(page, minimum_s: float = LOAD_S, timeout_s: float = 90.0) -> None:
    """Wait until the viewer has drawn the file: two screenshots 2 s apart are the same."""
    time.sleep(minimum_s)
    last = page.screenshot()
    waited = minimum_s
    while waited < timeout_s:
        time.sleep(2.0)
        waited += 2.0
        now = page.screenshot()
        if now == last:
            return
        last = now
    raise RuntimeError(f"the viewer kept changing for {timeout_s:.0f} s")


def _pixels(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)


def selected_tab(png: bytes, centres: list[int]) -> int | None:
    """The tab the viewer marks as selected: the one whose title sits in the blue pill.

    Rerun 0.41 draws a selected tab's title on a filled blue (≈ #186ADD) pill; a title
    under the mouse is only lightened.  None when no title is in a pill.
    """
    strip = _pixels(png)[TOP_BAR_PX + 4 : TOP_BAR_PX + TAB_BAR_PX - 4]
    r, b = strip[..., 0], strip[..., 2]
    blue = np.flatnonzero(((b > 150) & (b - r > 80)).sum(axis=0) >= 4)
    if blue.size == 0:
        return None
    inside = [k for k, x in enumerate(centres) if blue.min() <= x <= blue.max()]
    return inside[0] if len(inside) == 1 else None


def views_changed(before: bytes, after: bytes, share: float = 0.05) -> bool:
    """Whether the views below the tab bar differ (on ≥ ``share`` of their pixels)."""
    top = TOP_BAR_PX + TAB_BAR_PX
    a, b = _pixels(before)[top:], _pixels(after)[top:]
    return a.shape == b.shape and float(np.mean(np.any(a != b, axis=2))) >= share


def open_tab(page, shot: Shot, size: tuple[int, int], tries: int = 4) -> None:
    """Click the shot's tab title until the viewer shows that tab (checked, module docstring)."""
    width, height = size
    before = page.screenshot()
    centres = tab_centres(before, width)
    if len(centres) <= shot.tab:
        raise RuntimeError(f"{shot.file}: found tabs at {centres}, not tab {shot.tab}")
    seen = None
    for _ in range(tries):
        page.mouse.click(centres[shot.tab], TOP_BAR_PX + TAB_BAR_PX // 2)
        page.mouse.move(width // 2, height - 2)  # off the tab bar: no hover highlight
        settle(page, minimum_s=2.0)
        now = page.screenshot()
        seen = selected_tab(now, centres)
        if seen == shot.tab and views_changed(before, now):
            return
    raise RuntimeError(
        f"{shot.file}: tab {shot.tab} did not open (the viewer shows tab {seen} selected, "
        f"tabs at x = {centres})"
    )


def render(shots: list[Shot], docs: Path, chromium: str, size: tuple[int, int]) -> list[Path]:
    """Screenshot every shot in the web viewer; returns the PNGs written."""
    import rerun as rr
    from playwright.sync_api import sync_playwright

    docs.mkdir(parents=True, exist_ok=True)
    written = []
    viewer_port = 9090
    rr.serve_web_viewer(web_port=viewer_port, open_browser=False)
    roots = {shot.file.parent for shot in shots}
    with contextlib.ExitStack() as stack:
        bases = {root: stack.enter_context(file_server(root)) for root in roots}
        playwright = stack.enter_context(sync_playwright())
        profile = stack.enter_context(_temporary_directory())
        # A fresh profile each run (Playwright passes it as --user-data-dir).
        browser = playwright.chromium.launch_persistent_context(
            profile,
            executable_path=chromium,
            args=CHROMIUM_ARGS,
            viewport={"width": size[0], "height": size[1]},
        )
        for shot in shots:
            page = browser.new_page()
            url = f"{bases[shot.file.parent]}/{shot.file.name}"
            page.goto(f"http://127.0.0.1:{viewer_port}/?url={url}&renderer=webgl")
            settle(page)
            if shot.tab is not None:
                open_tab(page, shot, size)
            target = docs / shot.png
            target.write_bytes(small_png(page.screenshot()))
            written.append(target)
            page.close()
        browser.close()
    return written


@contextlib.contextmanager
def _temporary_directory():
    import tempfile

    with tempfile.TemporaryDirectory(prefix="render-rrd-") as path:
        yield path


def main() -> None:
    """Make the files, render every shot, list the PNGs."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "render")
    ap.add_argument("--docs", type=Path, default=ROOT / "docs" / "rerun")
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    ap.add_argument("--size", default="1920x1080", help="viewport WxH in px")
    args = ap.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    files = make_files(args.out)
    shots = [
        Shot(files["session"], "session.png"),
        Shot(files["clipped"], "session_clipped.png"),
        Shot(files["batch"], "batch.png"),
        Shot(files["batch"], "batch_sessions.png", tab=0),
        Shot(files["batch"], "batch_spin.png", tab=2),
        Shot(files["closed_loop"], "closed_loop.png", tab=1),
        Shot(files["closed_loop"], "closed_loop_calibration.png"),
    ]
    for path in render(shots, args.docs, args.chromium, size):
        shown = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
        print(f"{shown} ({path.stat().st_size / 1e3:.0f} kB)")


if __name__ == "__main__":
    main()
