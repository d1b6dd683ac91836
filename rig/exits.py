"""Exit codes and the one-line error of every `rig` subcommand."""

from __future__ import annotations

import sys

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130


def fail(message: str) -> int:
    """Bad input: say what and where on stderr; nothing was moved or written."""
    print(f"rig: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT
