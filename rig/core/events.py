"""The kinds of record in a dataset's events.jsonl (docs/dataset.md), one name each.

Written by the run engine, the drivers (a lamp supply's watchdog, a retry) and `rig import`; read back by
resume, the monitor and the report. One module low in the layers so that a driver and a reader spell a kind
the same way: the values are the on-disk format, never to be renamed.
"""

from __future__ import annotations

# -- the run's course (rig.acquisition) -------------------------------------------------------
DEVICES = "devices"                                   # connected: each device's identity
LAMP_ON = "lamp_on"
WARMUP_WAIT = "warmup_wait"                           # the warm-up waits for its next lamp check
WARMUP_CHECK = "warmup_check"                         # a warm-up check: E⊥ and its change
WARMUP_STABLE = "warmup_stable"
WARMUP_NOT_STABLE = "warmup_not_stable"
ILLUMINANCE = "illuminance"                           # an E⊥ measurement
POINT_PENDING = "point_pending"                       # a row written ahead of its E⊥ bracket
POINTS_DISCARDED = "points_discarded"                 # point ids to measure again, and why
FILTER = "filter"                                     # the filter wheel moved
ALIGNMENT_SCAN = "alignment_scan"
ALIGNED = "aligned"
ADAPTIVE_BATCH = "adaptive_batch"
SAMPLING_DONE = "sampling_done"
SUSPENDED = "suspended"
RESUMED = "resumed"                                   # a suspender cleared (not a `rig run --resume`: RESUME)
SUSPEND_TIMEOUT = "suspend_timeout"
STOP_REQUESTED = "stop_requested"
CLOSING_READING_FAILED = "closing_reading_failed"
PENDING_WITHOUT_CLOSING_READING = "pending_without_closing_reading"
PARKED = "parked"
PARK_SKIPPED = "park_skipped"
INTERRUPTED = "interrupted"
FAILED = "failed"
SAFE_STATE = "safe_state"                             # always the run's last
RESUME = "resume"                                     # `rig run --resume` started
PENDING_RECOVERED = "pending_recovered"
IMPORTED = "imported"                                 # `rig import`

# -- the drivers (rig.drivers) ----------------------------------------------------------------
RETRY = "retry"
RECONNECT = "reconnect"
RECONNECT_FAILED = "reconnect_failed"
DEVICE_ERRORS = "device_errors"                       # a lamp supply's error queue
WARNING = "warning"                                   # a device's warning flag that did not stop it
WATCHDOG_EXPIRED_BEFORE_CONNECT = "watchdog_expired_before_connect"
WATCHDOG_EXPIRED = "watchdog_expired"
WATCHDOG_OFF = "watchdog_off"
WATCHDOG_FEED_FAILED = "watchdog_feed_failed"
LAMP_OUTPUT_BLOCKED = "lamp_output_blocked"
SWITCH_OFF_RAMP_FAILED = "switch_off_ramp_failed"

# -- the run's phase: phase.json beside events.jsonl (docs/dataset.md), what the monitor shows -----------------
PHASE_FILE = "phase.json"
STARTING = "starting"                                 # connected, the devices identified
WARMING_UP = "warm-up"                                # the lamp warming up (at the start, or after a pause)
ALIGNING = "aligning"                                 # the campaign's alignment on the specular peak
MEASURING = "measuring"
PAUSED = "paused"                                     # a suspender holds the run (detail: device: reason)
STOPPING = "stopping"                                 # a stop was asked for (detail: why)
CLOSING = "closing"                                   # the rig made safe; the manifest says how the run ended
#: Every phase a run writes.
PHASES = (STARTING, WARMING_UP, ALIGNING, MEASURING, PAUSED, STOPPING, CLOSING)
