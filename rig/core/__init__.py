"""What every layer shares: value types, errors, exit codes, the clock interface."""
