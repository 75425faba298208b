"""The words for each diagnosed cause, built once for the workbench, the CLI and reports."""

from __future__ import annotations

CAUSES = ("image", "sonar", "moved")

THRESHOLDS_NOTE = ("good: residual below 2 px and detector score 0.7 or more; doubtful: residual 2-5 px or "
                   "score 0.4-0.7; bad: residual above 5 px, score below 0.4, or flagged; an entry without a score "
                   "(\"outline seen\": the look where the sonar predicts the sphere) by its residual alone")
RESIDUAL_GOOD_PX, RESIDUAL_BAD_PX = 2.0, 5.0
SCORE_GOOD, SCORE_BAD = 0.7, 0.4

RESIDUAL_LABEL = "residual px: |image centre - sonar centre projected with the current calibration|"


def title(cause: str, capture: str, sensor: str) -> str:
    """A short title (a button's label)."""
    return {
        "image": f"{capture} {sensor}: image detection wrong",
        "sonar": f"{capture} sonar: sonar detection wrong",
        "moved": f"{capture}: target moved",
    }[cause]


def explain(cause: str, capture: str, sensor: str, miss_px: float, gap: float | None) -> str:
    """One sentence per cause: what was found, and the fix."""
    if cause == "image":
        return (f"{capture} {sensor}: the image detection is wrong. The detected circle is {miss_px:.0f} px from where "
                f"the sonar puts the sphere, and a round outline sits right there ({gap:.0f} px from the detected "
                f"one). Fix: click the sphere at the cyan ring in {sensor}'s image, or Reject.")
    if cause == "sonar":
        return (f"{capture} sonar: the sonar detection is wrong. The cloud holds a sphere where the camera sees it, "
                f"{100 * gap:.0f} cm from the detected centre. Fix: drag the handle to it (or pick it), or Reject.")
    return (f"{capture}: the target moved between the sonar scan and the image. Neither detection explains the "
            f"other: no sphere in the image where the sonar puts it, none in the cloud where the image puts it "
            f"(misses by {miss_px:.0f} px). Fix: Reject the capture.")


def verdict(score: float | None, residual_px: float | None, flagged: bool) -> str:
    """'good', 'doubtful' or 'bad' for one detection (thresholds in :data:`THRESHOLDS_NOTE`)."""
    if flagged or (score is not None and score < SCORE_BAD) or (residual_px is not None and residual_px > RESIDUAL_BAD_PX):
        return "bad"
    if (score is not None and score < SCORE_GOOD) or (residual_px is not None and residual_px > RESIDUAL_GOOD_PX):
        return "doubtful"
    return "good"
