"""The SM15K's commands as rig uses them: one table, long forms, as the manual "Ethernet & Sequencer
Programming SM15K" (rev. July 2021) writes them; the driver's behaviour is in rig.drivers.delta_sm."""

from __future__ import annotations

from rig.drivers.line_instrument import Query, Setting, choice, number

#: Entries the supply's error queue holds (manual §5.6.7); the warning queue is read with the same bound.
ERROR_QUEUE_SIZE = 10
#: The watchdog's range (manual §5.6.10), ms.
WATCHDOG_MIN_MS, WATCHDOG_MAX_MS = 20, 10000
MAKER = "DELTA ELEKTRONIKA"
#: Status register A bits that keep the output from feeding the lamp (manual §5.8), and what they mean.
BLOCKING_BITS = {2048: "interlock open (the supply's interlock input)", 4096: "remote shut-down (RSD) active",
                 1024: "AC input fail (ACF)", 256: "over-temperature (OT)", 64: "DC output fail (DCF)"}


def plain(value: float) -> str:
    """<NR2> as the manual writes it: a plain decimal with four digits, never `1e-05`, never `-0.0000`."""
    return f"{round(value, 4) + 0.0:.4f}"


def error_entry(reply: str) -> tuple[int, str]:
    """`SYSTem:ERRor?` answers `code,text`; code 0 means the queue is empty."""
    code, comma, _ = reply.partition(",")
    if not comma:
        raise ValueError(reply)
    return int(code), reply


def limit_value(reply: str) -> float:
    """`SYSTem:LIMits:…?`: the manual does not publish the reply's format; take the leading number
    (a trailing `,ON` or `,1` is allowed)."""
    return float(reply.partition(",")[0])


# -- the command table (long forms, as the manual recommends) ------------------------------------
IDENTITY = Query("*IDN?", str)
CLEAR_STATUS = Setting("*CLS")
REMOTE_CV = Setting("SYSTem:REMote:CV {}")          # REMote | LOCal: who programs the voltage
REMOTE_CC = Setting("SYSTem:REMote:CC {}")          # ... and the current
MAX_CURRENT = Query("SOURce:CURrent:MAXimum?", number, "A")
MAX_VOLTAGE = Query("SOURce:VOLtage:MAXimum?", number, "V")
CURRENT_LIMIT = Setting("SYSTem:LIMits:CURrent {},ON", "A")   # <NR2>,<boolean>: ON = limit enabled
CURRENT_LIMIT_VALUE = Query("SYSTem:LIMits:CURrent?", limit_value, "A")
VOLTAGE_LIMIT = Setting("SYSTem:LIMits:VOLtage {},ON", "V")
VOLTAGE_LIMIT_VALUE = Query("SYSTem:LIMits:VOLtage?", limit_value, "V")
VOLTAGE = Setting("SOURce:VOLtage {}", "V")
CURRENT = Setting("SOURce:CURrent {}", "A")
CURRENT_SETPOINT = Query("SOURce:CURrent?", number, "A")
OUTPUT = Setting("OUTPut {}")                        # ON | OFF
#: `OUTPut?` answers 1/0 (ON/OFF on some firmware).
OUTPUT_STATE = Query("OUTPut?", choice({"1": True, "ON": True, "0": False, "OFF": False}))
MEASURED_CURRENT = Query("MEASure:CURrent?", number, "A")
MEASURED_VOLTAGE = Query("MEASure:VOLtage?", number, "V")
ERROR = Query("SYSTem:ERRor?", error_entry)
WARNING = Query("SYSTem:WARning?", error_entry)     # `0,None` when there is none (manual §5.6.8)
STATUS_A = Query("STATus:REGister:A?", int)          # a decimal bit field (manual §5.8)
WATCHDOG_ARM = Setting("SYSTem:COMmunicate:WATchdog SET,{:d}", "ms")
WATCHDOG_STOP = Setting("SYSTem:COMmunicate:WATchdog STOP")
#: Remaining ms while armed (the query, a valid command, also restarts it); 0: it had expired; -1: off.
WATCHDOG_STATE = Query("SYSTem:COMmunicate:WATchdog?", int, "ms")
