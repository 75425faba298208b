"""The Plan tab in real Chromium (Debian's, headless, Playwright) against a live workbench.

The operator opens the Plan tab of a session with seven accepted captures and two cameras,
asks for a tight target through the page's number fields (the plan re-runs: "Not yet", ghost
spheres drawn in the 3D view where the suggestions are, numbered rings on each camera's image
exactly as the server drew them), then a loose one ("Enough", and the "Enough captures" notice).
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from browser_util import canvas_box, only_client, screen_of, shot, wait_for
from test_cli_plan import planning_session

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def plan_wb(tmp_path_factory):
    from app.server import Workbench

    tmp = tmp_path_factory.mktemp("plan")
    wb = Workbench(planning_session(tmp / "s"), port=0, uploads_dir=tmp / "uploads")
    assert wb.wait_idle(60)
    yield wb
    wb.stop()


def _set_number(page, label: str, value: float) -> None:
    box = page.get_by_label(label)
    box.fill(str(value))
    box.press("Enter")


def _page_images(page) -> list:
    """Every decoded <img> of the page as RGB arrays (drawn through a canvas)."""
    got = page.evaluate("""() => [...document.querySelectorAll('img')].filter(i => i.complete && i.naturalWidth)
        .map(img => { const c = document.createElement('canvas'); c.width = img.naturalWidth; c.height = img.naturalHeight;
                      const g = c.getContext('2d'); g.drawImage(img, 0, 0);
                      return {w: c.width, h: c.height, rgba: Array.from(g.getImageData(0, 0, c.width, c.height).data)}; })""")
    return [np.asarray(g["rgba"], np.uint8).reshape(g["h"], g["w"], 4)[..., :3] for g in got]


def _ghost_patches(page, client, suggestions) -> list:
    """RGB patches (21x21 px) of a screenshot where each suggestion's centre is on screen."""
    img = shot(page, "workbench_plan_ghosts.png")[..., ::-1].astype(int)
    box = canvas_box(page)
    out = []
    for s in suggestions:
        x, y = (int(round(c)) for c in screen_of(client, box, s.X_sonar_m))
        if box["x"] + 10 <= x < box["x"] + box["width"] - 10 and box["y"] + 10 <= y < box["y"] + box["height"] - 10:
            out.append(img[y - 10:y + 11, x - 10:x + 11])
    return out


def _ghosts_on_screen(page, wb, client, suggestions) -> None:
    """The ghost spheres are drawn: where a suggestion is on screen, its patch turns orange when
    "Show suggestions in the 3D view" is on, and changes back when it is off."""
    page.wait_for_timeout(1500)  # the software renderer draws the ghosts
    shown = _ghost_patches(page, client, suggestions)
    assert shown, "no suggestion in the view"
    page.get_by_role("checkbox", name="Show suggestions in the 3D view").uncheck()
    wait_for(lambda: not wb.plan.nodes, 20, "the ghosts hidden")
    page.wait_for_timeout(1500)
    hidden = _ghost_patches(page, client, suggestions)
    orange = [(a[..., 0] - a[..., 2]).mean() - (b[..., 0] - b[..., 2]).mean() for a, b in zip(shown, hidden)]
    assert max(orange) > 15, orange  # at least one ghost visibly tints its place
    page.get_by_role("checkbox", name="Show suggestions in the 3D view").check()
    wait_for(lambda: len(wb.plan.nodes) == 2 * len(suggestions), 20, "the ghosts back")


def test_plan_tab_in_chromium(browser, plan_wb):
    wb = plan_wb
    before = set(wb.server.get_clients())
    page = browser.new_page()
    page.goto(wb.url)
    page.get_by_text("Captures (worst first)").wait_for()
    only_client(wb, before)
    assert wb.wait_idle(60)
    page.get_by_role("tab", name="Plan", exact=True).click()
    page.get_by_text("Where the next sphere capture helps most").wait_for()

    # a tight target: not yet met; three suggestions as ghost spheres and rings
    _set_number(page, "Target rotation 1-sigma (deg)", 0.001)
    _set_number(page, "Target translation 1-sigma (mm)", 0.1)  # both at their minimum
    wait_for(lambda: float(wb.plan.rot.value) == 0.001 and float(wb.plan.trans.value) == 0.1, 20, "the target set")
    assert wb.wait_idle(60)
    page.get_by_text(re.compile(r"Not yet")).first.wait_for()
    plan = wb.plan.last.plan
    assert not plan.met and len(plan.suggestions) == 3
    assert len(wb.plan.nodes) == 6  # a ghost sphere and a label per suggestion
    for k, s in enumerate(plan.suggestions, 1):
        assert np.allclose(wb.plan.nodes[2 * k - 2].position, s.X_sonar_m)
    client = next(iter(wb.server.get_clients().values()))
    _ghosts_on_screen(page, wb, client, plan.suggestions)
    for cam in ("cam1", "cam2"):
        ringed = np.asarray(wb.plan.images[f"cam:{cam}"].image)[..., :3]
        assert (np.abs(ringed.astype(int) - wb.state.image(wb.state.selected, cam)[..., :3]).sum(axis=2) > 60).any()
        # the page shows exactly the ringed image (sent as PNG: lossless)
        wait_for(lambda: any(im.shape == ringed.shape and np.array_equal(im, ringed) for im in _page_images(page)),
                 20, f"{cam}'s image with the suggestion rings in the page")
    shot(page, "workbench_plan_not_yet.png")

    # a loose target: enough, said in the tab and by a notice
    _set_number(page, "Target rotation 1-sigma (deg)", 20)
    _set_number(page, "Target translation 1-sigma (mm)", 1000)
    wait_for(lambda: float(wb.plan.trans.value) == 1000.0, 20, "the loose target set")
    assert wb.wait_idle(60)
    assert wb.plan.last.plan.met
    page.get_by_text("Enough captures").first.wait_for()  # the notice
    page.get_by_text(re.compile(r"Enough: every camera meets")).first.wait_for()
    shot(page, "workbench_plan_enough.png")
    page.close()
