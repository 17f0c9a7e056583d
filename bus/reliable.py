"""Publications that survive the radio link: zenoh-ext's advanced publisher and subscriber.

Every publication of a `Node` goes through an AdvancedPublisher that numbers its samples and keeps the
last ones in a cache; every subscriber of the bus (a Node's inputs, the recorder, the lock-step answer
watch) is an AdvancedSubscriber. When a link outage or a router restart hides some samples from a
subscriber, it sees a gap in a publisher's numbers, fetches the missing samples from that publisher's
cache, and delivers them in order, late but whole. Samples the cache no longer holds (an outage longer
than the cache covers) are a *loss*: counted exactly, per publisher, and handed to `on_loss`.

The cache of one publisher holds `LinkBudget.cache_samples(rate_hz, sample_bytes)` samples: the
publication rate times the longest outage to cover, bounded by a memory budget per publisher.

A gap is noticed when a later sample arrives, or from the publisher's heartbeat (its last sequence
number, every `heartbeat_s`): so the last samples published before an outage are recovered too, within a
heartbeat after the link is back. A subscriber delivers only what was published after it subscribed:

- a subscriber that hears a heartbeat of a publisher it has no sample of fetches that publisher's whole
  cache (zenoh-ext 1.10); so each subscriber first asks every cache for its latest sample (history of
  one), which gives it a starting point, and a restarted recorder costs the link one message per
  publisher, not every cache;
- that latest sample, and any other published before the subscription (by the publisher's timestamp),
  is not delivered: a restarted service must not handle again inputs of frames long answered, and a
  lock-step driver must not take an answer of its last flight for one of this flight. Sessions
  therefore run with timestamping on (bus/session.py). Clocks of the two hosts are assumed to agree
  to well within a frame.

Why not periodic queries (the other way zenoh-ext finds the last samples): a query that reaches a
publisher while its last sample is still crossing a slow link gets that sample again, and a 60 KB
cloud then crosses twice (measured on the 2 Mbit/s link: twice the bytes per frame).

Pinned: eclipse-zenoh==1.10.2 (pyproject.toml); zenoh-ext's API is marked unstable.
"""

from __future__ import annotations

import logging
import math
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass

import zenoh
import zenoh.ext as zext

from atr.errors import ConfigError
from bus import codec

log = logging.getLogger("atr")

MIB = 1024 * 1024


@dataclass(frozen=True)
class LinkBudget:
    """How much each publisher keeps for subscribers that missed it, and how often it says what it has.

    Attributes:
        outage_s: the longest link outage (or router restart) recovered with nothing lost, seconds.
        rate_hz: the highest publication rate of a data key, per second (a frame every 0.25 s at
            50 m range: atr/sim/config.py); Status keys publish at the Node's heartbeat instead.
        cache_bytes: memory one publisher's cache may hold, bytes; bounds the samples kept of a
            large message (a camera image) below `rate_hz * outage_s`.
        heartbeat_s: how often a publisher says its last sequence number (the delay to notice
            that the last samples before an outage were missed; ~90 bytes per publisher), seconds.
        linger_s: how long a closing Node keeps its publishers (and their caches) after its last
            status, seconds: a subscriber that finds a sample missing when that status arrives
            fetches it within a round trip over the link and the queue before it (a sample dropped
            on a congested link just before a service ends is otherwise lost with the process).

    Environment overrides (read by `from_env`): ATR_LINK_OUTAGE_S, ATR_LINK_RATE_HZ,
    ATR_LINK_CACHE_MB, ATR_LINK_HEARTBEAT_S, ATR_LINK_LINGER_S.

    """

    outage_s: float = 30.0
    rate_hz: float = 4.0
    cache_bytes: int = 16 * MIB
    heartbeat_s: float = 1.0
    linger_s: float = 0.5

    def __post_init__(self) -> None:
        for name in ("outage_s", "rate_hz", "heartbeat_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"link budget {name} {value!r} must be a number > 0")
        linger = self.linger_s
        if not (isinstance(linger, int | float) and math.isfinite(linger) and linger >= 0):
            raise ConfigError(f"link budget linger_s {linger!r} must be a number >= 0")
        if self.cache_bytes < 1:
            raise ConfigError(f"link budget cache_bytes {self.cache_bytes} must be >= 1")

    @classmethod
    def from_env(cls) -> LinkBudget:
        """Defaults, overridden by the ATR_LINK_* environment variables.

        Raises:
            ConfigError: a variable is not a number, or out of range.

        """
        fields: dict[str, float | int] = {}
        for env, name, scale in (
            ("ATR_LINK_OUTAGE_S", "outage_s", 1.0),
            ("ATR_LINK_RATE_HZ", "rate_hz", 1.0),
            ("ATR_LINK_CACHE_MB", "cache_bytes", MIB),
            ("ATR_LINK_HEARTBEAT_S", "heartbeat_s", 1.0),
            ("ATR_LINK_LINGER_S", "linger_s", 1.0),
        ):
            text = os.environ.get(env)
            if text is None:
                continue
            try:
                value = float(text) * scale
            except ValueError:
                raise ConfigError(f"{env}={text!r} must be a number") from None
            fields[name] = int(value) if name == "cache_bytes" else value
        return cls(**fields)

    def cache_samples(self, rate_hz: float, sample_bytes: int) -> int:
        """Samples a publisher of `rate_hz` messages of about `sample_bytes` bytes keeps (>= 1)."""
        wanted = math.ceil(rate_hz * self.outage_s)
        affordable = self.cache_bytes // max(1, sample_bytes)
        return max(1, min(wanted, affordable))


def declare_publisher(
    session: zenoh.Session,
    key: str,
    *,
    congestion: zenoh.CongestionControl,
    cache_samples: int,
    budget: LinkBudget,
) -> zext.AdvancedPublisher:
    """An AdvancedPublisher on `key`: sequence numbers, a heartbeat every `budget.heartbeat_s`, and
    a cache of `cache_samples` samples.

    Replies to recovery queries block rather than drop, whatever `congestion` the live samples use:
    a sample fetched again must arrive. The heartbeat is periodic, not sporadic: a sporadic one is
    sent only after a publication, and the one after a publication during an outage is lost with it.
    """
    return zext.declare_advanced_publisher(
        session,
        key,
        congestion_control=congestion,
        cache=zext.CacheConfig(
            cache_samples,
            replies_config=zext.RepliesConfig(congestion_control=zenoh.CongestionControl.BLOCK),
        ),
        sample_miss_detection=zext.MissDetectionConfig(
            heartbeat=budget.heartbeat_s, sporadic_heartbeat=None
        ),
    )


@dataclass(frozen=True)
class Loss:
    """Samples of one publisher that a subscriber will never get.

    Attributes:
        count: how many consecutive samples were lost.
        key: the key they were published on.
        source: the publishing process (`service@host:pid`, from the attachment), if known.
        publisher: the Zenoh publisher (`zid/eid`).

    """

    count: int
    key: str
    source: str | None
    publisher: str

    def reason(self) -> str:
        """The ErrorReport's reason; the count comes first (`LOSS_PREFIX` + count)."""
        return (
            f"{LOSS_PREFIX}{self.count} message(s) on {self.key} from {self.source or 'unknown'} "
            f"(publisher {self.publisher}): published while the link was down for longer than "
            "its cache covers"
        )


LOSS_PREFIX = "lost "


def loss_count(reason: str) -> int | None:
    """The count of a `Loss.reason()` text, or None for any other reason."""
    if not reason.startswith(LOSS_PREFIX):
        return None
    head = reason[len(LOSS_PREFIX) :].split(" ", 1)[0]
    return int(head) if head.isdigit() else None


class Subscriber:
    """An AdvancedSubscriber on `key_expr` that recovers missed samples and reports losses.

    Args:
        session: an open Zenoh session (not closed here).
        key_expr: what to subscribe to.
        on_sample: called with every sample published after this subscription, in each publisher's
            order (Zenoh's threads: keep it short).
        on_loss: called with each `Loss` (Zenoh's threads: keep it short).

    """

    def __init__(
        self,
        session: zenoh.Session,
        key_expr: str,
        on_sample: Callable[[zenoh.Sample], None],
        on_loss: Callable[[Loss], None] | None = None,
    ) -> None:
        self._on_sample = on_sample
        self._on_loss = on_loss
        self._lock = threading.Lock()
        # (zid, eid) -> (key, source) of the first sample heard from that publisher: names a Miss
        self._publishers: dict[tuple[str, int], tuple[str, str | None]] = {}
        self._delivering: set[tuple[str, int]] = set()  # publishers past their history
        self._since = session.new_timestamp().get_time_as_ntp64()
        self._subscriber = zext.declare_advanced_subscriber(
            session,
            key_expr,
            self._deliver,
            history=zext.HistoryConfig(max_samples=1),
            recovery=zext.RecoveryConfig(periodic_queries=None, heartbeat=True),
        )
        self._listener = self._subscriber.sample_miss_listener(self._missed)

    def _deliver(self, sample: zenoh.Sample) -> None:
        info = sample.source_info
        publisher = None
        if info is not None and info.source_id is not None:
            publisher = (str(info.source_id.zid), int(info.source_id.eid))
        with self._lock:
            if publisher is not None and publisher not in self._publishers:
                attachment = sample.attachment.to_bytes() if sample.attachment else None
                decoded = codec.decode_attachment(attachment)
                source = decoded[2] if decoded else None
                self._publishers[publisher] = (str(sample.key_expr), source)
            if publisher not in self._delivering and _before(sample, self._since):
                return  # history, not news: only the starting point of this publisher's numbers
            if publisher is not None:
                self._delivering.add(publisher)
        self._on_sample(sample)

    def _missed(self, miss: zext.Miss) -> None:
        publisher = (str(miss.source.zid), int(miss.source.eid))
        with self._lock:
            key, source = self._publishers.get(publisher, ("?", None))
        loss = Loss(int(miss.nb), key, source, f"{publisher[0]}/{publisher[1]}")
        log.warning("%s", loss.reason())
        if self._on_loss is not None:
            self._on_loss(loss)

    def undeclare(self) -> None:
        """Stop receiving."""
        self._listener.undeclare()
        self._subscriber.undeclare()


def _before(sample: zenoh.Sample, ntp64: object) -> bool:
    """True when the sample's publisher stamped it before `ntp64` (unstamped: False)."""
    stamp = sample.timestamp
    return stamp is not None and stamp.get_time_as_ntp64() < ntp64


def is_sequenced(sample: zenoh.Sample) -> bool:
    """True when Zenoh numbers this sample's publisher (an AdvancedPublisher): its gaps are Zenoh's
    to recover and to report, not the application's.
    """
    info = sample.source_info
    return info is not None and info.source_sn is not None
