"""Run a command and record its exit code and peak memory: python run_measured.py RESULT.json [--limit BYTES] -- CMD...

A child's peak memory (ru_maxrss) counts the memory of the process it was forked from, so a test
process of a gigabyte or more would swamp the figure. This launcher is a small process of its own:
the command it starts is forked from it, and the figure is the command's.
"""

import json
import os
import resource
import subprocess
import sys


def main() -> None:
    result, rest = sys.argv[1], sys.argv[2:]
    limit = None
    if rest[0] == "--limit":
        limit, rest = int(rest[1]), rest[2:]
    command = rest[1:] if rest[0] == "--" else rest

    def limit_address_space() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    child = subprocess.Popen(command, preexec_fn=limit_address_space if limit else None)
    _, status, usage = os.wait4(child.pid, 0)
    child.returncode = code = os.waitstatus_to_exitcode(status)
    with open(result, "w") as f:
        json.dump({"code": code, "peak_rss_mb": usage.ru_maxrss / 1024.0}, f)


if __name__ == "__main__":
    main()
