"""The workbench's plan panel: re-plans live, ghost spheres, rings on images, coverage pictures."""

from __future__ import annotations

import pytest

from test_cli_plan import planning_session


@pytest.fixture()
def wb(tmp_path):
    from app.server import Workbench

    w = Workbench(planning_session(tmp_path / "s"), port=0, uploads_dir=tmp_path / "uploads")
    assert w.wait_idle(60)
    yield w
    w.stop()


def test_plan_panel_follows_the_detections_and_the_target(wb):
    p = wb.plan
    assert p.last is not None and len(p.last.plan.suggestions) == 3
    assert len(p.nodes) == 6  # a ghost sphere and a label per suggestion
    assert {"cam:cam1", "cam:cam2", "cov:cam1", "cov:cam2", "cov:depth", "cov:fan"} <= set(p.images)
    assert "Next" not in p.status.content and ("Not yet" in p.status.content or "Enough" in p.status.content)
    p.rot.value, p.trans.value = 0.001, 0.01
    assert wb.wait_idle(60) and "**Not yet**" in p.status.content
    wb.state.set_status("p03", "rejected", "test")
    assert wb.wait_idle(60)
    assert len(p.last.taken_sonar_m) == 6  # the rejected capture no longer counts
    p.count.value = 1
    p.rot.value, p.trans.value = 20.0, 1000.0
    assert wb.wait_idle(60) and "**Enough**" in p.status.content and len(p.nodes) == 2
    p.show.value = False
    assert wb.wait_idle(60) and p.nodes == []
