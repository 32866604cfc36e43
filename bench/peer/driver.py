#!/usr/bin/python3
"""The [DISPLAY] of the headless LinuxCNC: runs the benchmark's programs one after another.

Started by the ``linuxcnc`` script as ``driver.py -ini FILE``, as the unprivileged user,
with Debian's /usr/bin/python3 (it has the ``linuxcnc`` module); it imports nothing of
ours. It reads ``rows.json`` next to the INI: a list of {name, marker, start, program}.
It starts ``halsampler -t`` into ``samples.txt`` (one line per servo period), resets the
E-stop, switches the machine on, homes every joint (in place: HOME_SEARCH_VEL = 0), and
per row: MDI to the start position, ``M68 E0 Q<marker>``, program_open + AUTO_RUN, polls
until the interpreter is idle, ``M68 E0 Q0``. Errors from LinuxCNC are kept per row.
It writes ``driver.json`` and exits, which shuts LinuxCNC down.
"""
import json
import os
import subprocess
import sys
import time
import traceback

import linuxcnc

ROW_TIMEOUT = 180.0  # s of wall time for one program


def main() -> int:
    ini = sys.argv[sys.argv.index("-ini") + 1]
    workdir = os.path.dirname(os.path.abspath(ini))
    with open(os.path.join(workdir, "rows.json")) as f:
        rows = json.load(f)
    log = {"rows": [], "errors": [], "started": time.time()}
    s, c, e = linuxcnc.stat(), linuxcnc.command(), linuxcnc.error_channel()

    def errors():
        out = []
        while True:
            msg = e.poll()
            if not msg:
                return out
            out.append(str(msg[1]).strip())

    def wait(pred, timeout):
        end = time.time() + timeout
        while time.time() < end:
            s.poll()
            if pred():
                return True
            time.sleep(0.01)
        return False

    def idle():
        return s.interp_state == linuxcnc.INTERP_IDLE and s.queue == 0 and s.inpos

    def mdi(text, timeout=60.0):
        c.mode(linuxcnc.MODE_MDI)
        c.wait_complete()
        c.mdi(text)
        c.wait_complete()
        time.sleep(0.02)
        return wait(idle, timeout)

    out = open(os.path.join(workdir, "samples.txt"), "w")
    sampler = subprocess.Popen(["halsampler", "-t"], stdout=out, stderr=subprocess.PIPE)
    try:
        if not wait(lambda: s.task_state in (linuxcnc.STATE_ESTOP, linuxcnc.STATE_ESTOP_RESET,
                                             linuxcnc.STATE_OFF, linuxcnc.STATE_ON), 30.0):
            raise RuntimeError("task never came up")
        c.state(linuxcnc.STATE_ESTOP_RESET)
        c.wait_complete()
        c.state(linuxcnc.STATE_ON)
        c.wait_complete()
        if not wait(lambda: s.task_state == linuxcnc.STATE_ON, 10.0):
            raise RuntimeError("machine did not switch on: %s" % errors())
        c.mode(linuxcnc.MODE_MANUAL)
        c.wait_complete()
        c.teleop_enable(0)
        c.wait_complete()
        c.home(-1)
        c.wait_complete()
        if not wait(lambda: all(s.homed[i] for i in range(s.joints)), 30.0):
            raise RuntimeError("homing failed: %s" % errors())
        c.teleop_enable(1)
        c.wait_complete()
        log["errors"] += errors()
        for row in rows:
            entry = {"name": row["name"], "marker": row["marker"], "errors": []}
            start = time.time()
            if not mdi(row["start"]):
                entry["errors"].append("start position not reached")
            mdi("M68 E0 Q%d" % row["marker"])
            c.mode(linuxcnc.MODE_AUTO)
            c.wait_complete()
            c.program_open(row["program"])
            c.wait_complete()
            c.auto(linuxcnc.AUTO_RUN, 0)
            c.wait_complete()
            time.sleep(0.05)
            entry["finished"] = wait(idle, ROW_TIMEOUT)
            entry["errors"] += errors()
            mdi("M68 E0 Q0")
            entry["errors"] += errors()
            entry["wall_s"] = time.time() - start
            log["rows"].append(entry)
        time.sleep(0.5)
    except Exception:  # noqa: BLE001 - everything goes to the log, LinuxCNC must shut down
        log["errors"].append(traceback.format_exc())
    finally:
        subprocess.call(["halcmd", "setp", "sampler.0.enable", "0"])
        time.sleep(1.0)  # let halsampler drain the FIFO
        sampler.terminate()
        try:
            _, err = sampler.communicate(timeout=10)
            log["halsampler_stderr"] = err.decode(errors="replace")[-2000:]
        except subprocess.TimeoutExpired:
            sampler.kill()
        out.close()
        log["finished"] = time.time()
        with open(os.path.join(workdir, "driver.json"), "w") as f:
            json.dump(log, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
