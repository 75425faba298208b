"""What a field or ROV video camera does to a frame, for the held-out kind "rov"
(:mod:`calib_core.synth.photo.rov`). The model, per effect:

- Dome port edge (:func:`dome_edge`): the housing seen past the rim of the dome port darkens
  the corners: radiance times a soft circular mask (radius ``radius_px`` about the image
  centre, fall-off over ``soft_px``) and the dark housing colour ``housing`` where the mask is 0.
- Lateral chromatic aberration (:func:`chromatic_aberration`): red magnified by ``1 + ca`` and
  blue by ``1 - ca`` about the image centre (green is the reference), so colour fringes grow
  towards the corners (``ca`` 0.001-0.004: 0.5-2 px at a PAL frame's corner).
- Interlace (:func:`interlace`): the even rows from one field, the odd rows from the other (the
  two fields are exposed a field period apart: a moving ball is combed).
- Chroma subsampling (:func:`chroma_subsample`): the frame in Y'CbCr (BT.601, OpenCV's
  YCrCb), chroma reduced to half in both directions (4:2:0) or a quarter across (4:1:1) by
  area averaging, a further low-pass across the line (``bleed_px``, an analog chroma
  bandwidth) and a horizontal chroma delay ``shift_px`` (colour bleeding beside an edge), then
  back to full size by bilinear interpolation. Luma is untouched.
- Low-bitrate compression (:func:`compress`): a JPEG round trip at a low quality (8x8 blocks,
  ringing), the look of an MPEG-2 / H.264 intra frame at a low bit rate.

Everything is an image operation (numpy / OpenCV); none moves the luma of a ball's outline
except the blocks and ringing of the compression.
"""

from __future__ import annotations

import cv2
import numpy as np

from calib_core.synth.photo.artefacts import jpeg


def dome_edge(radiance: np.ndarray, radius_px: float, soft_px: float, housing: tuple) -> np.ndarray:
    """Radiance (H,W,3) seen through a dome port whose rim cuts the corners (see the module doc)."""
    H, W = radiance.shape[:2]
    v, u = np.mgrid[0:H, 0:W].astype(np.float32)
    r = np.hypot(u - (W - 1) / 2, v - (H - 1) / 2)
    m = np.clip((radius_px - r) / max(soft_px, 1e-3), 0.0, 1.0)[:, :, None]
    return radiance * m + (1.0 - m) * np.asarray(housing, np.float32)[None, None, :]


def inside_dome(uv_px: np.ndarray, width_px: int, height_px: int, radius_px: float, soft_px: float) -> bool:
    """True when every point (N,2) lies where the dome's mask is 1 (clear of its rim)."""
    r = np.hypot(uv_px[:, 0] - (width_px - 1) / 2, uv_px[:, 1] - (height_px - 1) / 2)
    return bool((r < radius_px - soft_px - 2.0).all())


def chromatic_aberration(radiance: np.ndarray, ca: float) -> np.ndarray:
    """Radiance (H,W,3) with red magnified by 1 + ca and blue by 1 - ca about the centre."""
    if ca == 0:
        return radiance
    H, W = radiance.shape[:2]
    v, u = np.mgrid[0:H, 0:W].astype(np.float32)
    cu, cv_ = (W - 1) / 2, (H - 1) / 2
    out = radiance.astype(np.float32).copy()
    for ch, mag in ((0, 1.0 + ca), (2, 1.0 - ca)):
        # the channel magnified by mag: the output pixel p shows the input at centre + (p - centre) / mag
        mu = (cu + (u - cu) / mag).astype(np.float32)
        mv = (cv_ + (v - cv_) / mag).astype(np.float32)
        out[:, :, ch] = cv2.remap(out[:, :, ch], mu, mv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return out


def interlace(field_even: np.ndarray, field_odd: np.ndarray) -> np.ndarray:
    """A frame whose even rows come from ``field_even`` and odd rows from ``field_odd``."""
    out = np.array(field_even, copy=True)
    out[1::2] = field_odd[1::2]
    return out


def chroma_subsample(img: np.ndarray, scheme: str, bleed_px: float = 0.0, shift_px: float = 0.0) -> np.ndarray:
    """RGB uint8 (H,W,3) with its chroma subsampled ("420" or "411"), low-passed and delayed."""
    if scheme not in ("420", "411"):
        raise ValueError(f"unknown chroma scheme {scheme!r}")
    H, W = img.shape[:2]
    ycc = cv2.cvtColor(img, cv2.COLOR_RGB2YCrCb).astype(np.float32)
    small = (max(1, W // 2), max(1, H // 2)) if scheme == "420" else (max(1, W // 4), H)
    chroma = cv2.resize(ycc[:, :, 1:], small, interpolation=cv2.INTER_AREA)
    chroma = cv2.resize(chroma, (W, H), interpolation=cv2.INTER_LINEAR)
    if bleed_px > 0:
        chroma = cv2.GaussianBlur(chroma, (0, 0), sigmaX=bleed_px, sigmaY=1e-3)
    if shift_px:
        M = np.float32([[1, 0, shift_px], [0, 1, 0]])
        chroma = cv2.warpAffine(chroma, M, (W, H), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    ycc[:, :, 1:] = chroma
    return cv2.cvtColor(np.clip(np.round(ycc), 0, 255).astype(np.uint8), cv2.COLOR_YCrCb2RGB)


def compress(img: np.ndarray, quality: int) -> np.ndarray:
    """RGB uint8 through a low-bit-rate intra-frame coder (a JPEG round trip at ``quality``)."""
    return jpeg(img, quality)
