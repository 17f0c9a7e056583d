"""Auditing a recording: from the file alone, which software and configuration made each decision,
whether anything is missing, and whether the file was closed cleanly.

`audit(path)` reads a recording once (every segment of it, cut ones included: what is there is
read, the cut is reported) and gathers:

- provenance: the recorder's `provenance` metadata record of each segment (package version, source
  commit and hash, library versions, host, UAV, layout, configuration hash, input recording's hash);
  a configuration that differs between segments is reported as a change;
- completeness per publisher (one publisher per key): count, first and last log time, and every
  break in its sequence numbers (a gap: sent and lost; a reset to 0: the publisher restarted), plus
  the recorder's own `events` (segments continued after a restart, keys refused);
- errors by service over time (`atr/{uav}/{service}/errors`);
- every decision: each detection with its evidence (template, descriptor, score, overlap, inliers),
  the frames it came from and its world position;
- one answer per frame: a camera frame with neither Detections nor an ErrorReport is named;
- a clean-close check: the file has its summary and footer (a recorder killed with -9 leaves none).

Problems (anything missing or inconsistent) make `AuditReport.problems`; `atr audit` exits 1 when
there is one. `render_html` writes one self-contained page (inline CSS, the figure as an inline PNG).
"""

from __future__ import annotations

import base64
import html
import io
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.records import Channel, DataEnd, Footer, Message, Metadata
from mcap.stream_reader import StreamReader

from atr.errors import AtrError, RecordingError
from bus import codec
from bus.mcap_tools import segments
from bus.provenance import END_METADATA_NAME
from bus.provenance import METADATA_NAME as PROVENANCE


@dataclass
class Publisher:
    """What one key's publisher sent, as seen in the recording."""

    topic: str
    count: int = 0
    first_ns: int = 0
    last_ns: int = 0
    last_seq: int | None = None
    gaps: list[tuple[int, int, int]] = field(default_factory=list)  # (after seq, next seq, log ns)
    restarts: list[int] = field(default_factory=list)  # log ns of a sequence reset

    def lost(self) -> int:
        """Messages sent and not recorded (sum of the gaps)."""
        return sum(nxt - after - 1 for after, nxt, _ in self.gaps)


@dataclass
class Decision:
    """One detection and the evidence it rests on."""

    log_ns: int
    stamp_ns: int
    frame_seqs: list[int]
    target: str
    descriptor: str
    score: float
    overlap: float
    inliers: int
    position_m: tuple[float, float, float]


@dataclass
class AuditReport:
    """Everything `audit` found; `problems` is empty when the recording is complete and consistent."""

    files: list[str]
    provenance: list[dict[str, Any]] = field(default_factory=list)
    publishers: dict[str, Publisher] = field(default_factory=dict)
    errors: list[tuple[int, str, str]] = field(default_factory=list)  # (log ns, service, reason)
    decisions: list[Decision] = field(default_factory=list)
    events: list[tuple[int, str]] = field(default_factory=list)  # the recorder's own reports
    ends: list[dict[str, str]] = field(default_factory=list)  # clean-close markers
    trajectory: list[tuple[int, float, float]] = field(default_factory=list)
    frames: int = 0
    unanswered_frames: list[int] = field(default_factory=list)
    config_changes: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    closed: bool = True

    def summary(self) -> dict[str, Any]:
        """A JSON-able summary (what `atr audit --json` writes)."""
        return {
            "files": self.files,
            "closed": self.closed,
            "provenance": self.provenance,
            "publishers": {
                t: {
                    "count": p.count,
                    "first_ns": p.first_ns,
                    "last_ns": p.last_ns,
                    "lost": p.lost(),
                    "gaps": p.gaps,
                    "restarts": p.restarts,
                }
                for t, p in sorted(self.publishers.items())
            },
            "errors_by_service": dict(Counter(service for _, service, _ in self.errors)),
            "decisions": [d.__dict__ for d in self.decisions],
            "frames": self.frames,
            "unanswered_frames": self.unanswered_frames,
            "config_changes": self.config_changes,
            "events": self.events,
            "problems": self.problems,
        }


# Reading ----------------------------------------------------------------------------------------


def audit(path: str | Path) -> AuditReport:
    """Audit a recording (all its segments when it was continued after a recorder restart).

    Raises:
        RecordingError: the file does not exist or is not an MCAP file at all.

    """
    files = recording_files(path)
    report = AuditReport(files=[str(f) for f in files])
    answered: set[int] = set()
    frame_stamps: dict[int, int] = {}
    for f in files:
        _read_file(f, report, answered, frame_stamps)
    _check(report, answered, frame_stamps)
    return report


def recording_files(path: str | Path) -> list[Path]:
    """The segments of a recording, first to last: the file itself, then its continuations
    (`NAME.1.mcap`, `NAME.2.mcap`, ... written by a restarted recorder).

    Raises:
        RecordingError: the first file does not exist.

    """
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"recording {p} does not exist or is not a file")
    return segments(p)


def _read_file(
    path: Path, report: AuditReport, answered: set[int], frame_stamps: dict[int, int]
) -> None:
    channels: dict[int, str] = {}
    closed = False
    with path.open("rb") as f:
        try:
            for record in StreamReader(f).records:
                if isinstance(record, Channel):
                    channels[record.id] = record.topic
                elif isinstance(record, Message):
                    _take(
                        report, channels.get(record.channel_id, "?"), record, answered, frame_stamps
                    )
                elif isinstance(record, Metadata) and record.name == PROVENANCE:
                    report.provenance.append(dict(record.metadata))
                elif isinstance(record, Metadata) and record.name == END_METADATA_NAME:
                    report.ends.append(dict(record.metadata))
                elif isinstance(record, DataEnd | Footer):
                    closed = closed or isinstance(record, Footer)
        except Exception as exc:  # noqa: BLE001 - a cut file ends in any of the parsers' errors
            report.problems.append(f"{path.name} is cut short ({type(exc).__name__}: {exc})")
            closed = False
    if not closed:
        report.closed = False
        report.problems.append(
            f"{path.name} was not closed cleanly (no summary and footer): its recorder was killed"
        )


def _take(
    report: AuditReport,
    topic: str,
    message: Message,
    answered: set[int],
    frame_stamps: dict[int, int],
) -> None:
    publisher = report.publishers.setdefault(topic, Publisher(topic, first_ns=message.log_time))
    _count(publisher, message)
    kind = topic.rsplit("/", 1)[-1]
    if kind == "status" or topic.startswith("atr/templates/"):
        return
    decoded = _decode(message.data)
    if decoded is None:
        return
    if kind == "errors":
        service = topic.split("/")[2] if topic.count("/") >= 3 else topic
        reason = str(decoded.get("reason", ""))
        report.errors.append((message.log_time, service, reason))
        if service == "recorder":  # the recorder's reports are the recording's own events
            report.events.append((message.log_time, reason))
        if decoded.get("input_stamp_ns"):
            answered.add(int(decoded["input_stamp_ns"]))
    elif topic.endswith("/camera/image"):
        report.frames += 1
        frame_stamps[int(decoded.get("frame_seq", -1))] = int(decoded.get("stamp_ns", 0))
    elif topic.endswith("/detections"):
        answered.add(int(decoded.get("stamp_ns", 0)))
        report.decisions += _decisions(message.log_time, decoded)
    elif topic.endswith("/pose/camera"):
        T = decoded.get("T_world_cam")
        if T is not None:
            report.trajectory.append((message.log_time, float(T[0][3]), float(T[1][3])))


def _count(publisher: Publisher, message: Message) -> None:
    seq = message.sequence
    if publisher.last_seq is not None:
        if seq == 0 and publisher.last_seq > 0:
            publisher.restarts.append(message.log_time)
        elif seq > publisher.last_seq + 1:
            publisher.gaps.append((publisher.last_seq, seq, message.log_time))
    publisher.last_seq = seq
    publisher.count += 1
    publisher.last_ns = message.log_time


def _decisions(log_ns: int, message: dict[str, Any]) -> list[Decision]:
    out = []
    for d in message.get("detections", []):
        T = d["T_world_target"]
        out.append(
            Decision(
                log_ns=log_ns,
                stamp_ns=int(message.get("stamp_ns", 0)),
                frame_seqs=[int(s) for s in message.get("frame_seqs", [])],
                target=str(d["target"]),
                descriptor=str(d["descriptor"]),
                score=float(d["score"]),
                overlap=float(d["overlap"]),
                inliers=int(d["inliers"]),
                position_m=(float(T[0][3]), float(T[1][3]), float(T[2][3])),
            )
        )
    return out


def _decode(data: bytes) -> dict[str, Any] | None:
    try:
        message = codec.unpack(data)
    except AtrError:
        return None
    return message if isinstance(message, dict) else None


def _check(report: AuditReport, answered: set[int], frame_stamps: dict[int, int]) -> None:
    if not report.provenance:
        report.problems.append(
            "no provenance record: which software made this recording is unknown"
        )
    for i in range(1, len(report.provenance)):
        before, after = report.provenance[i - 1], report.provenance[i]
        for key in ("config_sha256", "package_version", "source_sha256"):
            if before.get(key) != after.get(key):
                report.config_changes.append(
                    f"segment {i}: {key} {before.get(key)} -> {after.get(key)}"
                )
    for topic, p in sorted(report.publishers.items()):
        for after, nxt, log_ns in p.gaps:
            report.problems.append(
                f"{topic}: {nxt - after - 1} message(s) lost (sequence {after} -> {nxt}) at log time {log_ns}"
            )
    if any(t.endswith("/detections") for t in report.publishers):
        report.unanswered_frames = sorted(
            seq for seq, stamp in frame_stamps.items() if stamp not in answered
        )
        if report.unanswered_frames:
            report.problems.append(
                f"{len(report.unanswered_frames)} camera frame(s) got neither detections nor an "
                f"error: {report.unanswered_frames[:20]}"
            )


# The page ---------------------------------------------------------------------------------------


def figure_png(report: AuditReport) -> bytes:
    """The flight on one page: the trajectory with the detections, and one time axis with every
    publisher's messages, gaps, restarts, errors and decisions.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_map, ax_time) = plt.subplots(
        1, 2, figsize=(13, 5), gridspec_kw={"width_ratios": [1, 2]}
    )
    if report.trajectory:
        _, xs, ys = zip(*report.trajectory, strict=True)
        ax_map.plot(xs, ys, "-", color="#4472c4", label="camera")
    if report.decisions:
        ax_map.scatter(
            [d.position_m[0] for d in report.decisions],
            [d.position_m[1] for d in report.decisions],
            marker="s",
            color="#c00000",
            label="detections",
        )
    ax_map.set(xlabel="x (m)", ylabel="y (m)", title="trajectory and detections", aspect="equal")
    if report.trajectory or report.decisions:
        ax_map.legend(loc="best", fontsize=8)
    t0 = min((p.first_ns for p in report.publishers.values()), default=0)
    topics = sorted(report.publishers)
    for row, topic in enumerate(topics):
        p = report.publishers[topic]
        ax_time.plot([(p.first_ns - t0) / 1e9, (p.last_ns - t0) / 1e9], [row, row], color="#aaaaaa")
        for _, _, log_ns in p.gaps:
            ax_time.plot((log_ns - t0) / 1e9, row, "v", color="#c00000", markersize=9)
        for log_ns in p.restarts:
            ax_time.plot((log_ns - t0) / 1e9, row, "|", color="#ff8c00", markersize=14)
    rows = {t: i for i, t in enumerate(topics)}
    for log_ns, service, _ in report.errors:
        row = next((i for t, i in rows.items() if t.endswith(f"/{service}/errors")), 0)
        ax_time.plot((log_ns - t0) / 1e9, row, "x", color="#c00000")
    det_row = next((i for t, i in rows.items() if t.endswith("/detections")), None)
    if det_row is not None:
        for d in report.decisions:
            ax_time.plot((d.log_ns - t0) / 1e9, det_row, "s", color="#2e7d32", markersize=4)
    ax_time.set_yticks(range(len(topics)), topics, fontsize=7)
    ax_time.set(xlabel="log time (s)", title="messages; gaps v, restarts |, errors x, decisions")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()


def render_html(report: AuditReport) -> str:
    """One self-contained HTML page of the audit (no external resources)."""
    e = html.escape
    verdict = (
        "complete and consistent" if not report.problems else f"{len(report.problems)} problem(s)"
    )
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>Audit</title>",
        "<style>body{font:14px sans-serif;margin:2em}table{border-collapse:collapse}"
        "td,th{border:1px solid #ccc;padding:2px 6px;text-align:left}"
        ".bad{color:#c00000}.ok{color:#2e7d32}</style></head><body>",
        f"<h1>Audit of {e(', '.join(Path(f).name for f in report.files))}</h1>",
        f"<p id='verdict' class='{'ok' if not report.problems else 'bad'}'>{e(verdict)}</p>",
    ]
    if report.problems:
        parts.append("<h2>Problems</h2><ul id='problems'>")
        parts += [f"<li class='bad'>{e(p)}</li>" for p in report.problems]
        parts.append("</ul>")
    parts.append("<h2>Provenance</h2>")
    for i, prov in enumerate(report.provenance):
        parts.append(f"<h3>segment {i}</h3>" + _table(["field", "value"], sorted(prov.items())))
    if report.config_changes:
        parts.append("<h2>Configuration changes</h2><ul>")
        parts += [f"<li>{e(c)}</li>" for c in report.config_changes]
        parts.append("</ul>")
    png = base64.b64encode(figure_png(report)).decode()
    parts.append(
        f"<h2>The flight</h2><img id='figure' alt='flight' src='data:image/png;base64,{png}'>"
    )
    t0 = min((p.first_ns for p in report.publishers.values()), default=0)
    rows = [
        (t, p.count, f"{(p.first_ns - t0) / 1e9:.3f}", f"{(p.last_ns - t0) / 1e9:.3f}", p.lost())
        + (len(p.restarts),)
        for t, p in sorted(report.publishers.items())
    ]
    parts.append(f"<h2>Publishers</h2><p>log times in s from {t0} ns</p>")
    header = ["key", "messages", "first s", "last s", "lost", "restarts"]
    parts.append(_table(header, rows, "publishers"))
    by_service: dict[str, int] = defaultdict(int)
    for _, service, _ in report.errors:
        by_service[service] += 1
    parts.append(
        "<h2>Errors by service</h2>" + _table(["service", "errors"], sorted(by_service.items()))
    )
    parts.append("<h2>Decisions</h2>")
    decision_rows = [
        (
            d.stamp_ns,
            ",".join(map(str, d.frame_seqs)),
            d.target,
            d.descriptor,
            f"{d.score:.3f}",
            f"{d.overlap:.3f}",
            d.inliers,
            "({:.2f}, {:.2f}, {:.2f})".format(*d.position_m),
        )
        for d in report.decisions
    ]
    header = [
        "stamp ns",
        "frames",
        "target",
        "descriptor",
        "score",
        "overlap",
        "inliers",
        "position m",
    ]
    parts.append(_table(header, decision_rows, "decisions"))
    if report.events:
        parts.append("<h2>Recorder events</h2>" + _table(["log ns", "event"], report.events))
    parts.append("</body></html>")
    return "\n".join(parts)


def _table(header: list[str], rows: list[tuple[Any, ...]], table_id: str = "") -> str:
    e = html.escape
    head = "".join(f"<th>{e(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{e(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    ident = f" id='{table_id}'" if table_id else ""
    return f"<table{ident}><tr>{head}</tr>{body}</table>"
