"""Runs INSIDE the guest (stdlib only): the commands the host drops into a folder, one at a
time, each answered with its output and exit status.

Why files and not the console: the results folder is the one channel every engine shares
(9p under QEMU, hostfs under user-mode Linux), and files keep a command's output apart from
the kernel's messages. Protocol, in the folder given as the only argument:

- the host writes ``N.sh`` (via a temporary name and a rename, so it is complete when seen);
- the agent runs ``/bin/sh N.sh`` with stdout in ``N.out`` and stderr in ``N.err``, then
  writes ``N.rc`` (the exit status, again through a rename): the host waits for that file;
- ``stop`` ends the agent (and so the boot script, and the guest powers off).

The agent writes ``ready`` once it polls. Usage: ``python agent.py FOLDER``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

POLL_S = 0.005  # a listing over 9p costs about 0.1 ms under TCG: 5 ms polls cost ~2 %


def serve(folder: str) -> int:
    done: set[str] = set()
    with open(os.path.join(folder, "ready.tmp"), "w") as ready:
        ready.write(f"{os.getpid()}\n")
    os.rename(os.path.join(folder, "ready.tmp"), os.path.join(folder, "ready"))
    while True:
        names = os.listdir(folder)
        if "stop" in names:
            return 0
        scripts = sorted((n for n in names if n.endswith(".sh") and n not in done),
                         key=lambda n: int(n.split(".")[0]))
        if not scripts:
            time.sleep(POLL_S)
            continue
        for name in scripts:
            done.add(name)
            stem = os.path.join(folder, name[:-3])
            with open(stem + ".out", "wb") as out, open(stem + ".err", "wb") as err:
                status = subprocess.call(["/bin/sh", os.path.join(folder, name)],
                                         stdin=subprocess.DEVNULL, stdout=out, stderr=err)
            with open(stem + ".rc.tmp", "w") as rc:
                rc.write(f"{status}\n")
            os.rename(stem + ".rc.tmp", stem + ".rc")


if __name__ == "__main__":
    raise SystemExit(serve(sys.argv[1]))
