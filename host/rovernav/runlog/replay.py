"""`rovernav replay LOG.mcap`: the host's mission code again, against what a log recorded.

A run log holds, in order, everything that reached the host's Mission: its ticks, the camera's
detections, every frame it took from the rover, a failure imposed from outside, a new host
process (`/host/inputs`, `/link/rover_to_host`), and the mission it was built from (the
`rovernav.run` metadata: a MissionSpec). Replay builds that Mission again, with no rover, no
camera and no simulator, feeds it those inputs at their recorded times, and compares what it
sends with what the recorded host sent (`/link/host_to_rover`): message by message, and path
by path.

With the same code and settings the two are identical (the test of a faithful log). With a
planner setting changed (`--set planner.robot_radius_m=0.14`) or new planner code, replay shows
where the host would have decided differently: the first message that differs and every path
side by side. From that point on the recorded rover was answering the recorded host, not this
one: replay is open loop, so what follows the first difference says what the new host would
have sent to that rover, not what a new run would do.
"""

from __future__ import annotations

import collections
import dataclasses
import json
import math
import tempfile
from collections.abc import Callable
from pathlib import Path

from ..errors import InputError
from ..link import messages_gen as mg
from ..link.framing import Frame
from ..mission import Detection
from ..mission.core import Recorder
from ..mission.spec import MissionSpec, start_host
from .channels import LOG_FORMAT, LOG_VERSION, META_RUN

#: Largest log replay reads (a 15-minute run with images at 2 Hz is about 40 MB).
MAX_LOG_BYTES = 4 * 1024**3


class LogFileError(InputError):
    """Not a rovernav run log, or one this version cannot replay."""


@dataclasses.dataclass
class RecordedRun:
    spec: MissionSpec
    source: str
    meta: dict[str, str]
    summary: dict
    inputs: list[dict]  # host inputs and taken rover frames ("kind": "rx"), in the order they came
    sent: list[dict]  # the frames the host sent
    truncated: bool = False  # the log's end is missing (a run cut off): read up to its last whole chunk


#: The channels replay reads.
_TOPICS = ("/host/inputs", "/link/rover_to_host", "/link/host_to_rover")


def _read_indexed(f) -> tuple[dict, list]:
    """Metadata by name and the replay's messages, by the file's index (a log that was closed)."""
    from mcap.reader import make_reader

    reader = make_reader(f)
    metas = {r.name: dict(r.metadata) for r in reader.iter_metadata()}
    return metas, [(ch.topic, m.data) for _s, ch, m in reader.iter_messages(topics=list(_TOPICS))]


def _read_streamed(f) -> tuple[dict, list]:
    """The same, record by record from the start up to the first that cannot be read: what a run
    cut off before its log was closed (power lost, the process killed) left in its .partial file."""
    from mcap.records import Channel, Message, Metadata
    from mcap.stream_reader import StreamReader

    topics: dict[int, str] = {}
    metas: dict[str, dict] = {}
    messages: list = []
    try:
        for record in StreamReader(f, skip_magic=False).records:
            if isinstance(record, Channel):
                topics[record.id] = record.topic
            elif isinstance(record, Metadata):
                metas[record.name] = dict(record.metadata)
            elif isinstance(record, Message) and topics.get(record.channel_id) in _TOPICS:
                messages.append((topics[record.channel_id], record.data))
    except Exception:  # noqa: BLE001 - the damage, whatever the reader makes of it, ends what can be read
        pass
    return metas, messages


def read_log(path: str | Path) -> RecordedRun:
    """The replayable part of a run log; LogFileError naming the problem. A log whose end is
    missing (a run cut off) is read up to its last whole chunk (`RecordedRun.truncated`)."""
    path = Path(path)
    if not path.is_file():
        raise LogFileError(f"{path}: no such file" if not path.exists() else f"{path}: not a regular file")
    if path.stat().st_size > MAX_LOG_BYTES:
        raise LogFileError(f"{path}: {path.stat().st_size:,} bytes is past the {MAX_LOG_BYTES:,} replay reads")
    truncated = False
    with open(path, "rb") as f:
        try:
            metas, messages = _read_indexed(f)
        except Exception as exc:  # noqa: BLE001 - any damage: read what comes before it
            f.seek(0)
            metas, messages = _read_streamed(f)
            truncated = True
            if META_RUN not in metas:
                raise LogFileError(f"{path}: not a readable MCAP run log ({type(exc).__name__}: {exc})") from None
    meta = metas.get(META_RUN)
    if meta is None:
        raise LogFileError(f"{path}: an MCAP file, but not a rovernav run log (no {META_RUN} metadata)")
    if "rovers" in meta:
        raise LogFileError(
            f"{path}: a fleet's run log ({meta['rovers']} rovers, a channel set each under /roverK): "
            "replay takes a lone rover's log"
        )
    inputs, sent = [], []
    try:
        summary = {k: json.loads(v) for k, v in metas.get("rovernav.summary", {}).items()}
        for topic, data in messages:
            record = json.loads(data)
            if topic == "/link/host_to_rover":
                sent.append(record)
            elif topic == "/link/rover_to_host":
                inputs.append({**record, "kind": "rx"})
            else:
                inputs.append(record)
    except (ValueError, TypeError, UnicodeDecodeError) as exc:
        raise LogFileError(f"{path}: a record is not JSON ({exc})") from None
    if meta.get("format") != LOG_FORMAT:
        raise LogFileError(f"{path}: metadata format {meta.get('format')!r}, not {LOG_FORMAT}")
    if meta.get("version") != str(LOG_VERSION):
        raise LogFileError(f"{path}: run log version {meta.get('version')}; this rovernav replays {LOG_VERSION}")
    if meta.get("schema_hash") != f"0x{mg.SCHEMA_HASH:08X}":
        raise LogFileError(
            f"{path}: recorded with protocol schema {meta.get('schema_hash')}, this rovernav "
            f"speaks 0x{mg.SCHEMA_HASH:08X}: the frames cannot be decoded the same way"
        )
    try:
        spec = MissionSpec.from_json(meta["spec"])
    except (KeyError, ValueError) as exc:
        raise LogFileError(f"{path}: {exc}") from None
    try:
        inputs.sort(key=lambda r: r["n"])
        sent.sort(key=lambda r: r["n"])
    except (KeyError, TypeError) as exc:
        raise LogFileError(f"{path}: a record without its order number ({exc})") from None
    return RecordedRun(spec, meta.get("source", "?"), meta, summary, inputs, sent, truncated)


class _ReplayLink:
    """What the Mission sends goes nowhere (the recorder keeps it); what it receives is what the
    recorded host received in the same tick."""

    def __init__(self):
        self._seq = 0
        self.frames: collections.deque[Frame] = collections.deque()

    def send(self, message) -> int:
        message.values()  # the range checks a real link makes before a frame goes out
        seq = self._seq
        self._seq = (seq + 1) & 0xFF
        return seq

    def recv(self, timeout_s: float | None = 0.0) -> Frame | None:
        return self.frames.popleft() if self.frames else None


class _Outputs(Recorder):
    def __init__(self):
        self.sent: list[dict] = []
        self.events: list[tuple[float, str]] = []

    def host_tx(self, t_s, message, seq):
        self.sent.append(
            {
                "t_s": t_s,
                "type": message.NAME,
                "id": message.ID,
                "seq": seq,
                "payload_hex": message.pack().hex(),
                "fields": message.to_dict(),
            }
        )

    def host_event(self, t_s, text):
        self.events.append((t_s, text))


def _frame(record: dict) -> Frame:
    cls = mg.MESSAGES[record["id"]]
    payload = bytes.fromhex(record["payload_hex"])
    return Frame(record["id"], record["seq"], payload, cls.unpack(payload), record.get("counter"))


@dataclasses.dataclass
class ReplayResult:
    run: RecordedRun
    spec: MissionSpec
    sent: list[dict]
    events: list[tuple[float, str]]
    outcome: str
    error: str | None
    mission: object

    # ------------------------------------------------------------ comparing

    def first_difference(self) -> int | None:
        """Index of the first frame the replayed host sent differently (None: all the same)."""
        a, b = self.run.sent, self.sent
        for i in range(min(len(a), len(b))):
            if not _same(a[i], b[i]):
                return i
        if len(a) == len(b) or (self.run.truncated and len(b) > len(a)):
            return None  # a cut-off log ends where its last whole chunk ends: the host may say more
        return min(len(a), len(b))

    @property
    def identical(self) -> bool:
        return self.first_difference() is None

    def paths(self, recorded: bool) -> list[dict]:
        return paths_sent(self.run.sent if recorded else self.sent)

    def to_json(self) -> dict:
        i = self.first_difference()
        rec, new = self.paths(True), self.paths(False)
        out = {
            "identical": i is None,
            "frames_recorded": len(self.run.sent),
            "frames_replayed": len(self.sent),
            "paths_recorded": len(rec),
            "paths_replayed": len(new),
            "outcome_recorded": self.run.summary.get("host_outcome"),
            "outcome_replayed": self.outcome,
            "changed": _changes(self.run.spec, self.spec),
            "paths": [{"recorded": _path_json(a), "replayed": _path_json(b)} for a, b in _zip_longest(rec, new)],
        }
        if i is not None:
            out["first_difference"] = {
                "index": i,
                "recorded": _brief(self.run.sent, i),
                "replayed": _brief(self.sent, i),
            }
        return out


def _same(a: dict, b: dict) -> bool:
    return a["t_s"] == b["t_s"] and a["id"] == b["id"] and a["seq"] == b["seq"] and a["payload_hex"] == b["payload_hex"]


def _brief(frames: list[dict], i: int) -> dict | None:
    if i >= len(frames):
        return None
    f = frames[i]
    return {"t_s": f["t_s"], "type": f["type"], "seq": f["seq"], "fields": f["fields"]}


def _zip_longest(a: list, b: list):
    return [(a[i] if i < len(a) else None, b[i] if i < len(b) else None) for i in range(max(len(a), len(b)))]


def _path_json(p: dict | None) -> dict | None:
    if p is None:
        return None
    return {
        "t_s": p["t_s"],
        "path_id": p["path_id"],
        "length_m": round(p["length_m"], 4),
        "waypoints_m": [[x, y] for x, y in p["waypoints"]],
    }


def paths_sent(frames: list[dict]) -> list[dict]:
    """The paths a host sent, from its PATH frames (each chunk once; a re-sent chunk counts once):
    [{"t_s": first chunk's time, "path_id", "waypoints": [(x_m, y_m)], "length_m"}]."""
    by_id: dict[int, dict] = {}
    order: list[dict] = []
    for f in frames:
        if f["type"] != mg.Path.NAME:
            continue
        m = f["fields"]
        key = m["path_id"]
        p = by_id.get(key)
        if p is None or p["total"] != m["total"] or p.get("done"):
            if p is not None and p.get("done") and m["first_index"] in p["chunks"]:
                continue  # a re-sent chunk of a path already whole
            p = {"t_s": f["t_s"], "path_id": key, "total": m["total"], "chunks": {}}
            by_id[key] = p
            order.append(p)
        p["chunks"][m["first_index"]] = [(m["x_mm"][k] / 1000, m["y_mm"][k] / 1000) for k in range(m["count"])]
        if sum(len(c) for c in p["chunks"].values()) >= p["total"]:
            p["done"] = True
    out = []
    for p in order:
        pts = [pt for first in sorted(p["chunks"]) for pt in p["chunks"][first]]
        out.append(
            {
                "t_s": p["t_s"],
                "path_id": p["path_id"],
                "waypoints": pts,
                "length_m": sum(math.dist(a, b) for a, b in zip(pts, pts[1:])),
            }
        )
    return out


def _changes(a: MissionSpec, b: MissionSpec) -> dict:
    out = {}
    for f in dataclasses.fields(MissionSpec):
        va, vb = getattr(a, f.name), getattr(b, f.name)
        if f.name == "planner":
            out.update(
                {f"planner.{k}": [va.get(k), vb.get(k)] for k in sorted(set(va) | set(vb)) if va.get(k) != vb.get(k)}
            )
        elif va != vb and f.name != "host_boot_id":
            out[f.name] = [va, vb]
    return out


# ------------------------------------------------------------ running it


def replay(
    run: RecordedRun, spec: MissionSpec | None = None, progress: Callable[[float], None] | None = None
) -> ReplayResult:
    """Feed `run`'s recorded inputs to a Mission built from `spec` (default: the recorded one)."""
    spec = spec or run.spec
    outputs = _Outputs()
    with tempfile.TemporaryDirectory(prefix="rovernav-replay-") as workdir:
        link = _ReplayLink()
        mission = start_host(spec, link, Path(workdir), on_event=lambda t, text: None, recorder=outputs)
        try:
            if "initial_map" in run.meta:  # `rovernav run --map`: what the sonar had found before
                from ..mapping import SonarReading

                mission.map.replay([SonarReading(**r) for r in json.loads(run.meta["initial_map"])])
            mission = _feed(spec, run.inputs, link, mission, outputs, workdir, progress)
        except (KeyError, ValueError, TypeError) as exc:
            raise LogFileError(f"a host input of the log cannot be fed again ({type(exc).__name__}: {exc})") from None
    return ReplayResult(run, spec, outputs.sent, outputs.events, mission.outcome.value, mission.error, mission)


def _feed(spec, inputs, link, mission, outputs, workdir, progress):
    """Each recorded input to the mission, in order; returns the mission at the end (a host
    restart starts a new one)."""
    next_progress = 30.0
    i = 0
    while i < len(inputs):
        r = inputs[i]
        i += 1
        kind = r["kind"]
        t = r["t_s"]
        if progress is not None and t >= next_progress:
            next_progress += 30.0
            progress(t)
        if kind == "tick":
            link.frames.clear()
            while i < len(inputs) and inputs[i]["kind"] == "rx":
                link.frames.append(_frame(inputs[i]))
                i += 1
            mission.tick(t)
        elif kind == "detection":
            mission.on_detection(Detection(r["taken_s"], r["x_m"], r["y_m"], r["heading_deg"], r.get("reason")), t)
        elif kind == "fail":
            mission.fail(r["why"])
        elif kind == "new_host":
            link = _ReplayLink()
            mission = start_host(
                spec.with_boot_id(r["host_boot_id"]),
                link,
                Path(workdir),
                on_event=lambda t, text: None,
                recorder=outputs,
            )
        elif kind != "rx":  # (a frame outside a tick: none is; the mission reads only in tick)
            raise LogFileError(f"the log has a host input of unknown kind {kind!r}")
    return mission


# ------------------------------------------------------------ showing it


def report_text(result: ReplayResult, limit: int = 12) -> str:
    run = result.run
    lines = []
    if run.truncated:
        lines.append(
            f"the log ends early (a run cut off before its log was closed): read up to its last whole "
            f"chunk, {run.inputs[-1]['t_s'] if run.inputs else 0:.1f} s of the mission"
        )
    changes = _changes(run.spec, result.spec)
    if changes:
        lines.append("changed: " + ", ".join(f"{k} {a!r} -> {b!r}" for k, (a, b) in changes.items()))
    i = result.first_difference()
    rec_paths, new_paths = result.paths(True), result.paths(False)
    if i is None:
        lines.append(
            f"identical: the replayed host sent the same {len(result.sent)} frames at the same times "
            f"({len(rec_paths)} paths); outcome {result.outcome}"
        )
        return "\n".join(lines)
    a, b = _brief(run.sent, i), _brief(result.sent, i)
    lines.append(f"DIFFERENT from frame {i + 1} of {len(run.sent)} recorded ({len(result.sent)} replayed):")
    lines.append("  recorded: " + (_show(a) if a else "(nothing more)"))
    lines.append("  replayed: " + (_show(b) if b else "(nothing more)"))
    lines.append("  (from here on the recorded rover answered the recorded host: what follows is open loop)")
    differ = [
        k
        for k, (p, q) in enumerate(_zip_longest(rec_paths, new_paths))
        if p is None or q is None or p["waypoints"] != q["waypoints"] or p["t_s"] != q["t_s"]
    ]
    lines.append(
        f"paths: {len(rec_paths)} recorded, {len(new_paths)} replayed; "
        + (f"the first that differs is #{differ[0] + 1}" if differ else "all the same")
    )
    lines.append(f"  {'#':>2}  {'recorded':<34} {'replayed':<34} same")
    for k, (p, q) in enumerate(_zip_longest(rec_paths, new_paths)[:limit]):
        same = p is not None and q is not None and p["waypoints"] == q["waypoints"] and p["t_s"] == q["t_s"]
        lines.append(f"  {k + 1:>2}  {_show_path(p):<34} {_show_path(q):<34} {'yes' if same else 'NO'}")
    if len(rec_paths) > limit or len(new_paths) > limit:
        lines.append(f"  ... ({max(len(rec_paths), len(new_paths)) - limit} more)")
    lines.append(
        f"outcome: recorded {run.summary.get('host_outcome', '?')}, replayed {result.outcome}"
        + (f" ({result.error})" if result.error else "")
    )
    return "\n".join(lines)


def _show(f: dict) -> str:
    fields = ", ".join(f"{k}={v}" for k, v in f["fields"].items())
    return f"{f['t_s']:.2f} s {f['type'].upper()} seq {f['seq']}: {fields[:140]}"


def _show_path(p: dict | None) -> str:
    if p is None:
        return "-"
    return f"{p['t_s']:7.2f} s, {len(p['waypoints'])} wp, {p['length_m']:.2f} m"


def replay_picture(result: ReplayResult, path: Path) -> None:
    """The arena with the recorded paths (blue) and the replayed ones (magenta)."""
    from types import SimpleNamespace

    import cv2
    import numpy as np

    from ..arena_picture import Canvas, draw_arena
    from ..files import write_atomic
    from ..scenario import parse_scenario

    spec = result.spec
    if spec.scenario_toml is not None:
        sc = parse_scenario(spec.scenario_toml, "<run log scenario>")
    else:
        from ..scenario import Arena, Pose, Scenario, Target
        from ..scenario import Mission as ScMission

        sc = Scenario(
            "run", Arena(spec.arena_w_m, spec.arena_h_m), Pose(*spec.start_xy), Target(*spec.target_xy), ScMission(), ()
        )
    canvas = Canvas(sc.arena.width_m, sc.arena.height_m, px_per_m=min(400, 1600 / max(sc.arena.width_m, 1e-3)))
    draw_arena(canvas, SimpleNamespace(scenario=sc, mission=result.mission), result.mission.grid)
    img = canvas.img
    for paths, colour, width in ((result.paths(True), (200, 120, 0), 5), (result.paths(False), (200, 0, 200), 2)):
        for p in paths:
            if len(p["waypoints"]) > 1:
                cv2.polylines(img, [canvas.pts(p["waypoints"])], False, colour, width, cv2.LINE_AA)
    footer = np.full((60, img.shape[1], 3), 255, np.uint8)
    i = result.first_difference()
    lines = [
        "recorded paths: blue (wide); replayed: magenta",
        "identical"
        if i is None
        else f"first difference at {(_brief(result.run.sent, i) or _brief(result.sent, i))['t_s']:.2f} s; "
        + ", ".join(f"{k} {a} -> {b}" for k, (a, b) in _changes(result.run.spec, result.spec).items()),
    ]
    for k, line in enumerate(lines):
        cv2.putText(footer, line[:110], (10, 22 + 24 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (30, 30, 30), 1, cv2.LINE_AA)
    ok, png = cv2.imencode(".png", np.vstack([img, footer]))
    if not ok:
        raise RuntimeError("OpenCV could not encode the replay picture")
    write_atomic(Path(path), png.tobytes())
