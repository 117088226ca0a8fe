"""Which processes are still alive: for the tests that prove a run leaves nothing behind."""

import os
import time
from pathlib import Path


def live_processes(matches, settle=3.0):
    """The pids of live processes (zombies excluded) whose command line ``matches(cmdline bytes)``;
    processes that were just killed get up to ``settle`` seconds to go."""
    deadline = time.monotonic() + settle
    while True:
        found = set()
        for entry in os.listdir("/proc"):
            if not entry.isdigit():
                continue
            try:
                cmdline = Path(f"/proc/{entry}/cmdline").read_bytes()
                state = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()[0]
            except (OSError, IndexError):
                continue
            if state != "Z" and matches(cmdline):
                found.add(int(entry))
        if not found or time.monotonic() > deadline:
            return found
        time.sleep(0.1)
