"""``tools/render_rrd.py`` opens a tab only when the viewer shows that tab (issue 39).

The guide's ``closed_loop.png`` was the calibration tab: the tool took the hover
highlight of a tab title for a switch.  Synthetic screenshots of Rerun's tab bar: a
selected tab's title on its blue pill, a hovered one only lightened.
"""

from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import render_rrd as R

W, H = 400, 200
TABS = [40, 140, 260]  # x of each tab title


def _png(selected: int | None = None, hovered: int | None = None, views: int = 255) -> bytes:
    image = np.full((H, W, 3), 248, dtype=np.uint8)
    image[R.TOP_BAR_PX + R.TAB_BAR_PX :] = views  # the views below the tab bar
    y0, y1 = R.TOP_BAR_PX + 3, R.TOP_BAR_PX + R.TAB_BAR_PX - 3
    for k, x in enumerate(TABS):
        if k == selected:
            image[y0:y1, x - 30 : x + 30] = (24, 106, 221)  # the selected tab's pill
        elif k == hovered:
            image[y0:y1, x - 30 : x + 30] = (225, 225, 225)  # hover: only lightened
        image[y0 + 5 : y1 - 5, x - 20 : x + 20] = 30  # the title's ink
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return buffer.getvalue()


def test_the_selected_tab_is_read_off_its_pill():
    assert R.tab_centres(_png(), W) == pytest.approx(TABS, abs=1)
    assert R.selected_tab(_png(selected=2), TABS) == 2
    assert R.selected_tab(_png(selected=0), TABS) == 0
    assert R.selected_tab(_png(hovered=1), TABS) is None  # a hover is no selection
    assert R.selected_tab(_png(), TABS) is None


class _Page:
    """A page whose clicks only hover (the bug's symptom), or switch the tab."""

    def __init__(self, switches: bool) -> None:
        self.switches, self.shown = switches, _png(views=255)

    def screenshot(self) -> bytes:
        return self.shown

    def mouse_click(self, x, y) -> None:
        k = min(range(len(TABS)), key=lambda i: abs(TABS[i] - x))
        self.shown = _png(selected=k, views=200) if self.switches else _png(hovered=k)

    @property
    def mouse(self):
        page = self

        class Mouse:
            def click(self, x, y):
                page.mouse_click(x, y)

            def move(self, x, y):
                pass

        return Mouse()


def test_a_hover_is_not_taken_for_a_tab_switch(monkeypatch):
    monkeypatch.setattr(R, "settle", lambda page, minimum_s=0.0: None)
    shot = R.Shot(Path("closed_loop.rrd"), "closed_loop.png", tab=1)
    with pytest.raises(RuntimeError, match="did not open"):
        R.open_tab(_Page(switches=False), shot, (W, H), tries=2)
    R.open_tab(_Page(switches=True), shot, (W, H))  # opens: the pill and the views say so
