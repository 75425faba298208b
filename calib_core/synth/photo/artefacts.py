"""Camera artefacts of the photographic renderer (opt-in through
:class:`~calib_core.synth.photo.effects.Photo`; none by default).

- Defocus: the radiance convolved with a uniform disc of radius ``defocus_px`` (a thin lens
  out of focus; the disc is anti-aliased).
- Rolling exposure / camera shake: the whole frame convolved with a centred line kernel
  ``shake_px`` (dx, dy) (the camera turning during the exposure).
- JPEG: the 8-bit image encoded and decoded by OpenCV at ``jpeg_quality`` (60-90 for a
  consumer or machine-vision camera's stream); 4:2:0 chroma, blocking and ringing included.
High sensor gain is the noise of :class:`~calib_core.synth.camera_render.RenderOptions`
(read noise and the shot-noise scale) drawn larger by the case.

All kernels are centred, so the true centre of a ball does not move.
"""

from __future__ import annotations

import cv2
import numpy as np

from calib_core.synth.photo.effects import motion_kernel


def disc_kernel(radius_px: float) -> np.ndarray:
    """Normalised disc of ``radius_px`` (anti-aliased by 4x4 supersampling)."""
    n = int(np.ceil(radius_px)) + 1
    s = (np.arange(4 * (2 * n + 1)) + 0.5) / 4 - (n + 0.5)
    x, y = np.meshgrid(s, s)
    inside = (np.hypot(x, y) <= radius_px).astype(np.float32)
    k = inside.reshape(2 * n + 1, 4, 2 * n + 1, 4).mean(axis=(1, 3))
    return k / k.sum()


def optical_blur(radiance: np.ndarray, photo) -> np.ndarray:
    """The radiance (H,W,3) after defocus and shake (unchanged when ``photo`` has neither)."""
    out = radiance
    if photo.defocus_px > 0:
        out = cv2.filter2D(out.astype(np.float32), -1, disc_kernel(photo.defocus_px), borderType=cv2.BORDER_REFLECT)
    if len(photo.shake_px) == 2 and np.hypot(*photo.shake_px) > 0:
        out = cv2.filter2D(out.astype(np.float32), -1, motion_kernel(photo.shake_px), borderType=cv2.BORDER_REFLECT)
    return out


def jpeg(img: np.ndarray, quality: int) -> np.ndarray:
    """RGB uint8 image through a JPEG encode / decode at ``quality`` (0: unchanged)."""
    if not quality:
        return img
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(img, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
