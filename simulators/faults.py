"""Fault names of every protocol peer, and random fault schedules for soak runs.

The names are defined here once: each peer checks an injection against its
entry, and the soak schedules draw from the same entries. A schedule is data
(seeded, reproducible); the injector is a progress callback that fires each
fault once the run has completed the fault's point count, and replaces a
burnt-out lamp after the operator's delay (rig time).
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import Any

from rig.core.values import Progress


@dataclass(frozen=True)
class PeerFaults:
    """What one kind of peer can inject: `transient` faults spoil replies (a run survives them with
    retries only); `other` ones are the device's own (a refusal, an alarm, a burnt-out lamp)."""

    transient: tuple[str, ...]
    other: tuple[str, ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        return self.transient + self.other

    def check(self, fault: str, count: int) -> None:
        """ValueError unless `fault` is one of these and `count` at least 1."""
        if fault not in self.names:
            raise ValueError(f"unknown fault {fault!r}; known: {', '.join(self.names)}")
        if count < 1:
            raise ValueError(f"count must be at least 1, got {count}")


LAMP_FAULTS = PeerFaults(("no_reply", "garbled", "short", "disconnect"), ("error_queue", "burnout"))
METER_FAULTS = PeerFaults(("no_reply", "garbled", "short"), ("overload",))
AXIS_FAULTS = PeerFaults(("no_reply", "garbled", "disconnect"), ("exception", "alarm"))
ZABER_FAULTS = PeerFaults(("no_reply", "garbled", "short", "disconnect"), ("stall", "limit"))
ATTENUATOR_FAULTS = PeerFaults(("no_reply", "garbled"), ("stuck",))
#: Transient faults per peer of the simulated rig.
TRANSIENT = {"arm": AXIS_FAULTS.transient, "stage": AXIS_FAULTS.transient, "lamp": LAMP_FAULTS.transient,
             "meter": METER_FAULTS.transient}


@dataclass(frozen=True)
class Fault:
    after_points: int
    peer: str
    kind: str                   # a peer fault name, or "silence" (the peer stops answering for a while)
    count: int = 1


@dataclass
class FaultSchedule:
    faults: list[Fault]
    replace_lamp_after_s: float = 300.0

    @classmethod
    def random(cls, n_points: int, *, seed: int, transient: int, silences: int = 1, alarm: bool = True,
               burnout: bool = True) -> FaultSchedule:
        """`transient` retry-level faults, `silences` outages longer than the retries, an axis
        alarm and a lamp burn-out, at random points of a run of `n_points`."""
        rng = random.Random(seed)
        at = lambda: rng.randrange(2, max(n_points - 2, 3))    # noqa: E731 - a point inside the run
        faults = []
        for _ in range(transient):
            peer = rng.choice(sorted(TRANSIENT))
            faults.append(Fault(at(), peer, rng.choice(TRANSIENT[peer])))
        faults += [Fault(at(), rng.choice(("meter", "arm", "stage")), "no_reply", count=5) for _ in range(silences)]
        if alarm:
            faults.append(Fault(at(), rng.choice(("arm", "stage")), "alarm"))
        if burnout:
            faults.append(Fault(at(), "lamp", "burnout"))
        return cls(sorted(faults, key=lambda f: f.after_points))

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for f in self.faults:
            key = f"{f.peer}:{f.kind}" + (f"×{f.count}" if f.count > 1 else "")
            out[key] = out.get(key, 0) + 1
        return out


@dataclass
class FaultInjector:
    """Progress callback: injects the schedule's faults into `peers` as the run advances."""

    schedule: FaultSchedule
    peers: dict[str, Any]
    fired: list[Fault] = field(default_factory=list)
    _burnt_at: float | None = None

    def __call__(self, progress: Progress) -> None:
        for fault in self.schedule.faults:
            if fault not in self.fired and progress.done >= fault.after_points:
                self.fired.append(fault)
                peer = self.peers[fault.peer]
                if fault.kind == "burnout":
                    self._burnt_at = peer.world.clock.now()
                peer.inject(fault.kind, count=fault.count)
        lamp = self.peers["lamp"]
        if self._burnt_at is not None and lamp.world.clock.now() >= self._burnt_at + self.schedule.replace_lamp_after_s:
            lamp.world.lamp.replace()           # the operator fits a new lamp
            self._burnt_at = None

    def rebind(self, peers: dict[str, Any]) -> None:
        """After a restart (a resume) the faults go on into the new rig's peers."""
        self.peers = peers
