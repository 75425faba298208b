"""Names and paths from the user's files reach the terminal through rich, where ``[bold red]``,
``[link=...]`` or ``[/]`` are markup: they must print as the text they are (session 25, sec)."""

from __future__ import annotations

from conftest import edit_yaml, run_cli

NAME = "[bold red]ALL GOOD[/bold red] [x](y) [link=https://example.invalid]here[/link]"


def test_calibrate_prints_a_session_name_as_text(make_session, tmp_path, capsys):
    """calibrate's title printed the session name as rich markup: the tags vanished (and styled
    or hyperlinked the rest of the line)."""
    # 6 captures: in the 64 x 48 fixture p01's disc touches the border and is now refused as cut
    root = make_session(tmp_path, n_captures=6, cameras=("cam1",))
    edit_yaml(root / "session.yaml", lambda d: d.update(name=NAME))
    assert run_cli(["calibrate", str(root), "--no-loo", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert f"Calibration of {NAME}" in out, out[:500]


def test_paths_with_brackets_print_as_text(make_session, tmp_path, capsys):
    """A session folder named like markup: 'wrote ...' lines of detect and report lost the tag."""
    root = make_session(tmp_path, n_captures=3, cameras=("cam1",), folder="s[red]x[/red]")
    assert run_cli(["detect", str(root)]) == 0
    assert run_cli(["report", str(root)]) == 0
    out = capsys.readouterr().out.replace("\n", "")
    assert f"wrote {root / 'detections.yaml'}" in out and f"wrote {root / 'results' / 'report.html'}" in out, out[-800:]
    assert f"No calibration yet ({root / 'results' / 'calibration.json'} does not exist)" in out, out[-800:]
