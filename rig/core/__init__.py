"""What every layer shares: value types, errors, exit codes, the clock interface.

Owns: `values` (Window, SensorInfo, Frame, readings, Progress), `errors` (DeviceError), `exits` (exit codes
and the one-line error of every subcommand), `clock` (the Clock every wait goes through), `events` (the
kinds of record in events.jsonl, one name each), `motion` (the trapezoidal move model), `interrupts`
(SIGTERM and SIGHUP as Ctrl+C), `jsonfile` (JSON from a file anyone may have edited), `bands` (row bands
of the compiled kernels on every CPU).
May import: nothing of rig (the bottom layer): the standard library and numpy.
"""
