"""Launcher for tests/test_adversarial.py: run many ``sonarcal ARGV`` cases in ONE child
process (the imports are paid once), under an address-space limit so a bomb fails its
case instead of the machine.

For each case: the peak-RSS mark is reset (``/proc/self/clear_refs`` = 5), the CLI's
``main`` runs with fds 1 and 2 sent to files, then VmHWM (kB) and the CPU seconds the
case used are recorded. Usage: ``adversarial_launch.py CASES.json RESULTS.json`` where
CASES.json is ``[{"name": ..., "argv": [...], "cwd": ...}, ...]``.
"""

import json
import os
import resource
import sys
import tempfile

LIMIT_BYTES = int(os.environ.get("SONARCAL_AS_LIMIT", str(2 * 2**30)))


def _peak_kb() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    return -1


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def run_case(cli, case: dict) -> dict:
    saved = os.dup(1), os.dup(2)
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(out.fileno(), 1)
        os.dup2(err.fileno(), 2)
        os.chdir(case["cwd"])
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        t0 = _cpu()
        try:
            rc = cli(case["argv"])
        except BaseException as e:  # noqa: BLE001 - recorded as a failed case
            rc = f"{type(e).__name__}: {e}"[:300]
        cpu, peak = _cpu() - t0, _peak_kb()
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        out.seek(0)
        err.seek(0)
        return {"rc": rc, "out": out.read().decode(errors="replace"), "err": err.read().decode(errors="replace"),
                "peak_kb": peak, "cpu": cpu}


def main() -> int:
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT_BYTES, LIMIT_BYTES))
    import sonarcal_cli.main as entry

    with open(sys.argv[1]) as f:
        cases = json.load(f)
    results = {}
    for case in cases:
        results[case["name"]] = run_case(entry.main, case)
    with open(sys.argv[2], "w") as f:
        json.dump(results, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
