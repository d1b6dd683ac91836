"""Exit codes and the one-line error of every `rig` subcommand."""

from __future__ import annotations

import sys

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130
#: The reader of stdout went away (`rig plan … | head`): 128 + SIGPIPE, what a shell reports for any
#: command stopped by a closed pipe. Not 0, because the command may not have finished (e.g. `rig fit
#: … --json F | head` stops before writing F); never a traceback.
EXIT_BROKEN_PIPE = 141


def fail(message: str) -> int:
    """Bad input: say what and where on stderr; nothing was moved or written."""
    print(f"rig: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT
