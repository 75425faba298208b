"""``import_bag``: a ROS 1 / ROS 2 bag -> a session folder, streamed in two passes.

Pass 1 reads only the sonar message times (scan windows) and the first CameraInfo of each
camera. Pass 2 reads sonar and image messages in time order; a scan's clouds are held until
the scan ends, then written; of its frames only the one nearest the scan's middle is held.
Memory is bounded by one scan, not by the bag.
"""

from __future__ import annotations

from pathlib import Path

from calib_core.errors import SessionError
from calib_core.ingest import rosmsg
from calib_core.ingest.assemble import MAX_BACKGROUND_FRAMES, Assembler, ImportOptions, ImportResult
from calib_core.ingest.bag import list_topics, open_bag, pick_cameras, pick_sonar_topic, read_error
from calib_core.ingest.frames import FrameKeeper
from calib_core.ingest.motion import NS
from calib_core.ingest.scans import scan_index, split_scans
from calib_core.ingest.staging import StagedSession


def import_bag(source, out, opts: ImportOptions, progress=None) -> ImportResult:
    """Write session ``out`` from bag ``source``; SessionError (nothing written) on bad input."""
    source = Path(source)
    with open_bag(source) as reader:
        rows = list_topics(reader)
        sonar = pick_sonar_topic(source, rows, opts.sonar_topic)
        cams = pick_cameras(source, rows, opts.camera_topics)
        conns = {c.topic: c for c in reader.connections}
        models = _camera_models(reader, source, cams, opts, conns)
        times = _sonar_times(reader, source, sonar, progress)
        windows, rule = split_scans(times, opts.split, opts.gap_seconds, opts.scan_seconds)
        t0 = int(reader.start_time)
        topic_cam = {c.image_topic: c.name for c in cams}
        keeper = FrameKeeper(models, opts.diameter_m / 2, windows, t0, opts.tolerance_px, opts.tolerance_m,
                             opts.median)
        with StagedSession(out) as st:
            asm = Assembler(st, opts, windows, t0)
            cam_entries = {c.name: {"intrinsics": st.intrinsics(c.name, models[c.name])} for c in cams}
            bg = _Backgrounds(opts.background_window_s, t0, keeper)
            streams = [c for c in reader.connections if c.topic == sonar or c.topic in topic_cam]
            total = sum(int(c.msgcount) for c in streams)
            acc: dict[int, list] = {}
            frame_ids: dict[str, str] = {}
            for n, (conn, t, raw) in enumerate(_messages(reader, source, streams)):
                i = scan_index(windows, t)
                if conn.topic == sonar:
                    if i >= 0:
                        acc.setdefault(i, []).append(_decode(reader, source, conn, t, t0, raw, rosmsg.cloud_from_msg))
                else:
                    _image(reader, source, conn, t, t0, raw, i, topic_cam[conn.topic], keeper, bg, frame_ids)
                _flush(asm, keeper, acc, windows, t)
                if progress and n % 20 == 0:
                    progress(n, total, conn.topic)
            _flush(asm, keeper, acc, windows, None)
            for cam, rel in bg.write(st).items():
                cam_entries[cam]["background"] = rel
            src = {"kind": "ros1-bag" if source.suffix == ".bag" else "ros2-bag", "path": str(source.absolute()),
                   "sonar_topic": sonar, "scan_split": rule, "start_time_ns": t0,
                   "cameras": {c.name: {"image_topic": c.image_topic, "info_topic": c.info_topic} for c in cams}}
            return asm.manifest(cam_entries, src, source.stem, stereo=_stereo(reader, source, rows, cams, frame_ids))


def _sonar_times(reader, path, sonar: str, progress) -> list[int]:
    """Pass 1: the sonar messages' bag times (the data is read but not decoded)."""
    conns = [c for c in reader.connections if c.topic == sonar]
    total, times = sum(int(c.msgcount) for c in conns), []
    for conn, t, _ in _messages(reader, path, conns):
        times.append(t)
        if progress and len(times) % 50 == 0:
            progress(len(times), total, "finding scans")
    return times


def _messages(reader, path, connections):
    """reader.messages, with read failures (truncation, corruption) as one SessionError."""
    it = reader.messages(connections=connections)
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except Exception as e:
            raise read_error(path, e) from None
        yield item


def _decode(reader, path, conn, t, t0, raw, convert):
    try:
        msg = reader.deserialize(raw, conn.msgtype)
    except Exception as e:
        raise read_error(path, e) from None
    try:
        return convert(msg)
    except ValueError as e:
        raise SessionError(path, f"topic {conn.topic} at {(t - t0) / NS:.3f} s: {e}") from None


def _image(reader, path, conn, t, t0, raw, i, cam, keeper: FrameKeeper, bg, frame_ids: dict) -> None:
    """One image message: a background frame, a frame of scan ``i``, or (outside both) skipped."""
    if i < 0 and not bg.wants(t):
        return
    img, frame_ids[cam] = _decode(reader, path, conn, t, t0, raw,
                                  lambda m: (rosmsg.image_from_msg(m, conn.msgtype), m.header.frame_id))
    if i < 0:
        bg.add(cam, t, img)
        return
    bg.ready()
    try:
        keeper.add(cam, i, t, img)
    except ValueError as e:
        raise SessionError(path, f"topic {conn.topic} at {(t - t0) / NS:.3f} s: {e}") from None


def _stereo(reader, path, rows, cams, frame_ids: dict) -> dict:
    """``{T_<cam>_<cam1>: 4x4}`` from /tf_static: every other camera whose frame it links to the
    first camera's (two cameras: the stereo pair; three or more: each tied to the first)."""
    from calib_core.ingest.tf import edges_from_msgs, transform_between

    tf_conns = [c for c in reader.connections if c.msgtype == rosmsg.TF_STATIC and c.topic.endswith("tf_static")]
    if len(cams) < 2 or not tf_conns or cams[0].name not in frame_ids:
        return {}
    msgs = [_decode(reader, path, c, t, reader.start_time, raw, lambda m: m) for c, t, raw in _messages(reader, path, tf_conns)]
    edges, a = edges_from_msgs(msgs), cams[0]
    out = {}
    for b in cams[1:]:
        T = transform_between(edges, frame_ids[b.name], frame_ids[a.name]) if b.name in frame_ids else None
        if T is not None:
            out[f"T_{b.name}_{a.name}"] = [[round(float(v), 9) for v in row] for row in T]
    return out


def _camera_models(reader, path, cams, opts: ImportOptions, conns) -> dict:
    """Intrinsics per camera: a file given with --intrinsics, else the first CameraInfo."""
    from calib_core.io.intrinsics import load_intrinsics

    models = {c.name: load_intrinsics(opts.intrinsics[c.name], c.name, opts.intrinsics_entry.get(c.name))
              for c in cams if c.name in opts.intrinsics}
    unknown = set(opts.intrinsics) - {c.name for c in cams}
    if unknown:
        raise SessionError(path, f"--intrinsics for unknown camera(s) {', '.join(sorted(unknown))} "
                                 f"(cameras: {', '.join(c.name for c in cams)})")
    need = {c.info_topic: c.name for c in cams if c.name not in models and c.info_topic}
    missing = [c.name for c in cams if c.name not in models and not c.info_topic]
    if missing:
        raise SessionError(path, f"no CameraInfo topic for camera(s) {', '.join(missing)}: give --intrinsics NAME=FILE")
    if not need:  # every camera's intrinsics were given (rosbags reads every topic for an empty list)
        return models
    wanted = [conns[t] for t in need]
    for conn, t, raw in _messages(reader, path, wanted):
        if need.get(conn.topic) in models:
            continue
        name = need[conn.topic]
        models[name] = _decode(reader, path, conn, t, reader.start_time, raw, lambda m: rosmsg.camera_from_info(m, name))
        if all(n in models for n in need.values()):
            break
    silent = [f"{n} ({t})" for t, n in need.items() if n not in models]
    if silent:
        raise SessionError(path, f"no CameraInfo message for camera {', '.join(silent)}: give --intrinsics NAME=FILE")
    return models


def _flush(asm: Assembler, keeper: FrameKeeper, acc: dict, windows, t_ns) -> None:
    """Write every scan that ended before ``t_ns`` (all open scans when None)."""
    for i in range(len(windows)):
        if i in asm.done or (t_ns is not None and windows[i].end_ns >= t_ns):
            continue
        frames, motion = keeper.take(i)
        clouds = acc.pop(i, [])
        inten = [c[1] for c in clouds if c[1] is not None]
        asm.finish_scan(i, [c[0] for c in clouds], inten if len(inten) == len(clouds) else None, frames, motion,
                        windows[i].n_messages)
        asm.done.add(i)


class _Backgrounds:
    """Frames inside ``--background START:END`` (s from the bag start): written to backgrounds/,
    and their median becomes the background model the sphere tracking uses."""

    def __init__(self, window_s, t0, keeper: FrameKeeper):
        self.window = None if window_s is None else (t0 + int(window_s[0] * NS), t0 + int(window_s[1] * NS))
        self.keeper, self.frames, self._set = keeper, {}, False

    def wants(self, t) -> bool:
        return self.window is not None and self.window[0] <= t <= self.window[1]

    def add(self, cam, t, img) -> None:
        if self.wants(t) and len(self.frames.setdefault(cam, [])) < MAX_BACKGROUND_FRAMES:
            self.frames[cam].append(img)

    def ready(self) -> None:
        if self._set:
            return
        self._set = True
        from calib_core.detect.image.detect import background_model

        for cam, frames in self.frames.items():
            if frames:
                self.keeper.set_background(cam, background_model(frames))

    def write(self, st) -> dict:
        return {cam: st.image("backgrounds", cam, f"bg{j:02d}", f).rsplit("/", 1)[0] + "/"
                for cam, frames in self.frames.items() for j, f in enumerate(frames)}
