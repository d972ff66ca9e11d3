#!/usr/bin/env python3
"""Runs a command with a fresh temporary folder of its own, for tests that run concurrently.

    in_temp_dir.py PARENT COMMAND ARGS...

Every argument equal to {tmp} (or containing it) gets the path of a new folder made below PARENT
(mkdtemp: unique even when two test runs on one build tree start the same test at once). The
folder is removed when the command succeeds and kept, with its path printed, when it fails.
Exits with the command's exit code.
"""
import os
import shutil
import subprocess
import sys
import tempfile


def main():
    parent, command = sys.argv[1], sys.argv[2:]
    os.makedirs(parent, exist_ok=True)
    folder = tempfile.mkdtemp(prefix="run-", dir=parent)
    code = subprocess.call([arg.replace("{tmp}", folder) for arg in command])
    if code == 0:
        shutil.rmtree(folder, ignore_errors=True)
    else:
        print(f"in_temp_dir.py: kept {folder} (exit code {code})", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
