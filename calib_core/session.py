"""Session manifest (``session.yaml``, format sonar-camera-session/1): load and validate.

:func:`load_session` parses the manifest and raises :class:`SessionError` on the first
structural problem. :func:`validate_session` additionally opens every file the manifest
names and returns *every* problem found (for ``sonarcal info``).

Extensions to the contract (all optional):
- ``sonar.beam_width_deg``: beam cone width (default 1.0, BlueView BV5000).
- ``stereo``: ``{T_cam2_cam1: 4x4}`` stereo transforms between cameras (e.g. from
  ``sonarcal stereo``), keys ``T_<target>_<source>``.
- per camera ``background_window: [start_s, end_s]`` for a background video.
- per camera ``intrinsics_entry: cam0`` when ``intrinsics`` is a Kalibr camchain of several
  cameras (the entry's key); without it the entry whose camera_name or rostopic names the camera.
"""

from __future__ import annotations

import datetime
import math
import unicodedata
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calib_core.camera import CameraModel
from calib_core.errors import SessionError, short_repr
from calib_core.geometry import is_rigid
from calib_core.io.confine import confine_write
from calib_core.io.yaml_safe import read_yaml_mapping

SESSION_FORMAT = "sonar-camera-session/1"
MANIFEST = "session.yaml"


@dataclass(frozen=True)
class CameraSpec:
    """One camera of the rig. Paths are absolute, inside the session folder."""

    name: str
    intrinsics_path: Path
    background_path: Path | None = None
    background_window_s: tuple[float, float | None] = (0.0, None)
    intrinsics_entry: str | None = None  # the key of a Kalibr camchain's entry (cam0, ...)


@dataclass(frozen=True)
class Capture:
    """One sonar scan with the target held still, plus an image per camera."""

    id: str
    cloud_path: Path
    image_paths: dict[str, Path] = field(default_factory=dict)


@dataclass(frozen=True)
class Session:
    """A parsed session manifest. ``root`` is the absolute session folder."""

    root: Path
    name: str
    sphere_diameter_m: float
    cameras: dict[str, CameraSpec]
    captures: list[Capture]
    sonar_model: str = ""
    sound_speed_m_s: float | None = None
    beam_width_deg: float = 1.0
    measured_m: dict[str, float] = field(default_factory=dict)
    stereo: dict[str, np.ndarray] = field(default_factory=dict)
    raw: dict = field(default_factory=dict, repr=False)

    @property
    def manifest_path(self) -> Path:
        return self.root / MANIFEST

    @property
    def sphere_radius_m(self) -> float:
        return self.sphere_diameter_m / 2.0

    def capture(self, capture_id: str) -> Capture:
        for c in self.captures:
            if c.id == capture_id:
                return c
        raise SessionError(self.manifest_path, f"no capture '{capture_id}'")

    def camera_model(self, cam: str) -> CameraModel:
        """Load the intrinsics of camera ``cam`` (reads the file each call; cache in the shell)."""
        from calib_core.io.intrinsics import load_intrinsics

        if cam not in self.cameras:
            raise SessionError(self.manifest_path, f"no camera {short_repr(cam)} (cameras: {', '.join(self.cameras)})")
        spec = self.cameras[cam]
        return load_intrinsics(spec.intrinsics_path, cam, spec.intrinsics_entry)


def resolve_inside(root: Path, rel, manifest: Path, what: str) -> Path:
    """Resolve a manifest path relative to the session and refuse anything outside it.

    Absolute paths, ``..`` escapes and symlinks pointing out of the folder are refused.
    """
    if not isinstance(rel, str) or not rel.strip():
        raise SessionError(manifest, f"{what}: expected a relative path, got {short_repr(rel)}")
    if "\x00" in rel:
        raise SessionError(manifest, f"{what}: path holds a NUL character")
    if has_control(rel):
        raise SessionError(manifest, f"{what}: path {short_repr(rel)} holds control characters (a newline, an escape "
                                     "or a bidi override): rename the file")
    p = Path(rel)
    if p.is_absolute() or (len(rel) > 1 and rel[1] == ":") or rel.startswith("\\"):
        raise SessionError(manifest, f"{what}: absolute path '{rel}' is not allowed; paths are relative to the session folder")
    root_r = root.resolve()
    try:
        full = (root / p).resolve()
    except (OSError, RuntimeError):  # symlink loop, name too long
        raise SessionError(manifest, f"{what}: path '{rel}' cannot be resolved (symlink loop or bad name)") from None
    if full != root_r and root_r not in full.parents:
        raise SessionError(manifest, f"{what}: path '{rel}' leaves the session folder")
    return full


def _num(manifest, value, what, positive=True):
    if isinstance(value, str) and _YAML11_EXPONENT.match(value.strip()):
        value = float(value)  # YAML 1.1 reads 22e-2 (no dot) as a string; accept it as the number it is
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SessionError(manifest, f"{what} must be a number, got {short_repr(value)}")
    try:
        v = float(value)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v) or (positive and v <= 0):
        raise SessionError(manifest, f"{what} must be a {'positive ' if positive else ''}finite number, got {short_repr(value)}")
    return v


_YAML11_EXPONENT = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")


def load_session(folder: str | Path) -> Session:
    """Parse and structurally validate ``folder/session.yaml``."""
    root = _session_root(folder)
    manifest = confine_write(root, root / MANIFEST)  # a session.yaml symlinked out of the folder is refused
    data = read_yaml_mapping(manifest, "session manifest (session.yaml)")
    _check_format(manifest, data.get("format"))
    diameter = _sphere_diameter(manifest, data.get("sphere"))
    sonar, sound_speed, beam = _sonar_fields(manifest, data.get("sonar"))
    cameras = _cameras(root, manifest, data.get("cameras"))
    captures = _captures(root, manifest, data.get("captures"), cameras)
    measured = {}
    for k, v in _mapping(manifest, data.get("measured"), "measured").items():
        measured[str(k)] = _num(manifest, v, f"measured.{k}")
    stereo = {}
    for k, v in _mapping(manifest, data.get("stereo"), "stereo").items():
        stereo[str(k)] = parse_transform(manifest, v, f"stereo.{k}")

    return Session(
        root=root,
        name=_session_name(manifest, data.get("name"), root.name),
        sphere_diameter_m=diameter,
        cameras=cameras,
        captures=captures,
        sonar_model=_plain_text(manifest, sonar.get("model"), "sonar.model", ""),
        sound_speed_m_s=sound_speed,
        beam_width_deg=beam,
        measured_m=measured,
        stereo=stereo,
        raw=data,
    )


def _session_root(folder: str | Path) -> Path:
    """The absolute session folder (``folder``, or the folder of a session.yaml given instead)."""
    root = Path(folder)
    try:
        exists = root.exists()
    except (OSError, ValueError):
        exists = False
    if not exists:
        raise SessionError(root, "session folder not found")
    if root.is_file() and root.name == MANIFEST:
        root = root.parent
    if not root.is_dir():
        raise SessionError(root, "not a folder (give the session folder that holds session.yaml)")
    return root.resolve()


def _check_format(manifest: Path, fmt) -> None:
    if fmt is not None and (not isinstance(fmt, str) or not fmt.startswith("sonar-camera-session/")):
        raise SessionError(manifest, f"format {short_repr(fmt)} is not a sonar-camera-session format")
    if isinstance(fmt, str) and fmt != SESSION_FORMAT:
        raise SessionError(manifest, f"format {short_repr(fmt)} is not one this tool understands ({SESSION_FORMAT})")


def _sphere_diameter(manifest: Path, sphere) -> float:
    if not isinstance(sphere, dict) or "diameter" not in sphere:
        raise SessionError(manifest, "missing 'sphere: {diameter: METRES}'")
    diameter = _num(manifest, sphere["diameter"], "sphere.diameter")
    if diameter > 5.0:
        raise SessionError(manifest, f"sphere.diameter {diameter} m is implausible (metres expected, e.g. 0.22)")
    return diameter


def _sonar_fields(manifest: Path, sonar) -> tuple[dict, float | None, float]:
    """(the ``sonar`` mapping, its sound speed or None, its beam width in degrees)."""
    sonar = sonar or {}
    if not isinstance(sonar, dict):
        raise SessionError(manifest, "'sonar' must be a mapping")
    sound_speed = _num(manifest, sonar["sound_speed"], "sonar.sound_speed") if sonar.get("sound_speed") is not None else None
    if sound_speed is not None and not 1300 <= sound_speed <= 1700:
        raise SessionError(manifest, f"sonar.sound_speed {sound_speed} m/s is outside water's 1300-1700 m/s")
    beam = _num(manifest, sonar.get("beam_width_deg", 1.0), "sonar.beam_width_deg")
    if beam > 20:
        raise SessionError(manifest, f"sonar.beam_width_deg {beam} is implausible (degrees, e.g. 1.0)")
    return sonar, sound_speed, beam


def _cameras(root: Path, manifest: Path, cams_raw) -> dict[str, CameraSpec]:
    if not isinstance(cams_raw, dict) or not cams_raw:
        raise SessionError(manifest, "missing 'cameras' (a mapping of camera name to {intrinsics: ...})")
    cameras: dict[str, CameraSpec] = {}
    for name, spec in cams_raw.items():
        name = str(name)
        cameras[name] = _camera_spec(root, manifest, name, spec)
    return cameras


def _camera_spec(root: Path, manifest: Path, name: str, spec) -> CameraSpec:
    if name == "sonar":
        raise SessionError(manifest, "a camera may not be called 'sonar'")
    _check_name(manifest, name, "camera name")
    if not isinstance(spec, dict) or "intrinsics" not in spec:
        raise SessionError(manifest, f"cameras.{name}: missing 'intrinsics: PATH'")
    intr = resolve_inside(root, spec["intrinsics"], manifest, f"cameras.{name}.intrinsics")
    bg = spec.get("background")
    bgp = resolve_inside(root, bg, manifest, f"cameras.{name}.background") if bg is not None else None
    win = spec.get("background_window", [0.0, None])
    if not isinstance(win, list) or len(win) != 2:
        raise SessionError(manifest, f"cameras.{name}.background_window must be [start_s, end_s]")
    start = _num(manifest, win[0], f"cameras.{name}.background_window", positive=False)
    end = None if win[1] is None else _num(manifest, win[1], f"cameras.{name}.background_window", positive=False)
    entry = spec.get("intrinsics_entry")
    if entry is not None and (not isinstance(entry, str) or not 0 < len(entry) <= 64 or not entry.isprintable()):
        raise SessionError(manifest, f"cameras.{name}.intrinsics_entry must be a short name such as cam0")
    return CameraSpec(name, intr, bgp, (start, end), entry)


def _captures(root: Path, manifest: Path, caps_raw, cameras: dict) -> list[Capture]:
    if not isinstance(caps_raw, list) or not caps_raw:
        raise SessionError(manifest, "missing 'captures' (a list of {id, cloud, images})")
    captures: list[Capture] = []
    seen: set = set()
    for i, c in enumerate(caps_raw):
        captures.append(_capture(root, manifest, i, c, cameras, seen))
    return captures


def _capture(root: Path, manifest: Path, i: int, c, cameras: dict, seen: set) -> Capture:
    """Capture ``i`` of the manifest (its id is added to ``seen``, the ids so far)."""
    if not isinstance(c, dict):
        raise SessionError(manifest, f"captures[{i}] must be a mapping with id, cloud, images")
    cid = c.get("id")
    if cid is None or (not isinstance(cid, (str, int))) or str(cid).strip() == "":
        raise SessionError(manifest, f"captures[{i}]: missing 'id'")
    cid = str(cid)
    _check_name(manifest, cid, f"captures[{i}].id")
    if cid in seen:
        raise SessionError(manifest, f"captures[{i}]: duplicate id '{cid}'")
    seen.add(cid)
    if "cloud" not in c:
        raise SessionError(manifest, f"capture {cid}: missing 'cloud'")
    cloud = resolve_inside(root, c["cloud"], manifest, f"capture {cid} cloud")
    imgs_raw = c.get("images") or {}
    if not isinstance(imgs_raw, dict):
        raise SessionError(manifest, f"capture {cid}: 'images' must map camera names to paths")
    imgs = {}
    for cam, rel in imgs_raw.items():
        if str(cam) not in cameras:
            raise SessionError(manifest, f"capture {cid}: image for unknown camera '{cam}' (cameras: {', '.join(cameras)})")
        imgs[str(cam)] = resolve_inside(root, rel, manifest, f"capture {cid} image {cam}")
    return Capture(cid, cloud, imgs)


def _plain_text(manifest: Path, value, what: str, default: str) -> str:
    """A free-text field: a string or number of at most 200 characters (never str() of a tree)."""
    if value is None or value == "":
        return default
    if isinstance(value, (datetime.date, datetime.datetime)):
        value = value.isoformat()  # YAML reads an unquoted 2026-05-01 as a date
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        raise SessionError(manifest, f"{what} must be text, got a {type(value).__name__}")
    text = value if isinstance(value, str) else repr(value)
    if len(text) > 200 or has_control(text):
        raise SessionError(manifest, f"{what} must be one line of text of at most 200 characters "
                                     "(no control characters)")
    return text


def has_control(text: str) -> bool:
    """Control or format characters (newlines, ESC, bidi overrides): they would forge lines in
    the terminal, in exported files and in tables."""
    return any(unicodedata.category(ch) in ("Cc", "Cf") or ch in "\u2028\u2029" for ch in text)


def _session_name(manifest: Path, value, default: str) -> str:
    return _plain_text(manifest, value, "name", default)


def _check_name(manifest: Path, name: str, what: str) -> None:
    """Camera names and capture ids end up in file names (exports, thumbnails): no path tricks."""
    if not name.strip() or name in (".", "..") or any(ch in name for ch in "/\\\x00") or len(name) > 100 \
            or has_control(name):
        raise SessionError(manifest, f"{what} {short_repr(name)} is not allowed (no '/', '\\', '..', control "
                                     "characters, empty or over 100 characters)")


def _mapping(manifest: Path, value, what: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise SessionError(manifest, f"'{what}' must be a mapping, got {type(value).__name__}")
    return value


def parse_transform(path: Path, value, what: str) -> np.ndarray:
    """Validate a 4x4 rigid transform given as nested lists."""
    if isinstance(value, (str, bytes)):
        raise SessionError(path, f"{what} must be a finite 4x4 matrix of numbers")
    try:
        T = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError, RecursionError):
        raise SessionError(path, f"{what} must be a finite 4x4 matrix of numbers") from None
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise SessionError(path, f"{what} must be a finite 4x4 matrix, got shape {T.shape}")
    if not is_rigid(T):
        raise SessionError(path, f"{what} is not a rigid transform (rotation not orthonormal or last row not 0 0 0 1)")
    return T


@dataclass
class SessionCheck:
    """What :func:`validate_session` found: the session (None if the manifest is unusable),
    every problem, the camera models that loaded and each capture's cloud point count."""

    session: Session | None
    problems: list[SessionError]
    cameras: dict[str, CameraModel] = field(default_factory=dict)
    cloud_points: dict[str, int] = field(default_factory=dict)
    cloud_no_return: dict[str, int] = field(default_factory=dict)  # NaN/inf or (0, 0, 0) rows dropped, per capture


def validate_session(folder: str | Path) -> SessionCheck:
    """Open every file the manifest names; return the session and every problem found."""
    try:
        session = load_session(folder)
    except SessionError as e:
        return SessionCheck(None, [e])
    problems: list[SessionError] = []
    models = _check_cameras(session, problems)
    points = _check_captures(session, models, problems)
    _check_results(session, problems)
    return SessionCheck(session, problems, models, {c: n for c, (n, _) in points.items()},
                        {c: k for c, (_, k) in points.items() if k})


def _check_cameras(session: Session, problems: list) -> dict[str, CameraModel]:
    """Each camera's intrinsics and background (problems appended); the models that loaded."""
    from calib_core.io.images import load_background_frames
    from calib_core.io.intrinsics import load_intrinsics

    models: dict[str, CameraModel] = {}
    for name, spec in session.cameras.items():
        try:
            models[name] = load_intrinsics(spec.intrinsics_path, name, spec.intrinsics_entry)
        except SessionError as e:
            problems.append(e)
        if spec.background_path is not None:
            try:
                start, end = spec.background_window_s
                wh = (models[name].width_px, models[name].height_px) if name in models else None
                frames = load_background_frames(spec.background_path, wh, root=session.root, start_s=start, end_s=end)
                if name in models:
                    _check_size(spec.background_path, frames[0], models[name], problems)
            except SessionError as e:
                problems.append(e)
    return models


def _check_captures(session: Session, models: dict, problems: list) -> dict[str, tuple[int, int]]:
    """Each capture's cloud and images (problems appended); the clouds' point counts (finite
    points, points without a return)."""
    from calib_core.io.clouds import load_cloud
    from calib_core.io.images import load_image

    points: dict[str, tuple[int, int]] = {}
    for cap in session.captures:
        try:
            cloud = load_cloud(cap.cloud_path)
            points[cap.id] = (len(cloud), cloud.n_without_return)
        except SessionError as e:
            problems.append(e)
        for cam, p in cap.image_paths.items():
            try:
                img = load_image(p, (models[cam].width_px, models[cam].height_px) if cam in models else None)
                if cam in models:
                    _check_size(p, img, models[cam], problems)
            except SessionError as e:
                problems.append(e)
    return points


def _check_results(session: Session, problems: list) -> None:
    """detections.yaml and results/calibration.json, when present (problems appended)."""
    from calib_core.detections import load_detections
    from calib_core.results import calibration_path, load_calibration

    try:
        load_detections(session)
    except SessionError as e:
        problems.append(e)
    try:
        if calibration_path(session).exists():
            load_calibration(calibration_path(session))
    except SessionError as e:
        problems.append(e)


def _check_size(path: Path, img, cam: CameraModel, problems: list) -> None:
    h, w = img.shape[:2]
    if (w, h) != (cam.width_px, cam.height_px):
        problems.append(SessionError(path, f"image is {w} x {h} but its intrinsics say {cam.width_px} x {cam.height_px}"))
