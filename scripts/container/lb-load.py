#!/usr/bin/env python3
"""Load through a load balancer while replicas die: THREADS clients send
POST /v1/forward for SECONDS; at each `--event T:COMMAND` (seconds after
the start) COMMAND runs in a shell (e.g. `podman kill replica-2`). A client
retries a request once on a connection error (nothing else). Prints the
counts and latencies as JSON; exit 1 if any request went unanswered or
answered 5xx.

Usage: lb-load.py URL --seconds 20 --threads 8 --event 6:'podman kill r2'
"""

import argparse
import json
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request

TREE = {
    "positions": [[0, 0, 0], [0, 0, 0.4], [0.02, 0, 0.8], [0.25, 0.05, 0.55]],
    "parents": [None, 0, 1, 1],
    "radius": [None, 0.015, 0.008, 0.006],
}
BODY = json.dumps({"tree": TREE, "contact_node": 3, "push": [0, 0.05, 0]}).encode()


def one_request(url):
    """(status or None, seconds, retried)."""
    for attempt in (0, 1):
        started = time.perf_counter()
        request = urllib.request.Request(
            url + "/v1/forward", data=BODY, headers={"Content-Type": "application/json"}
        )
        try:
            with urllib.request.urlopen(request, timeout=30) as response:
                response.read()
                return response.status, time.perf_counter() - started, attempt > 0
        except urllib.error.HTTPError as e:
            e.read()
            return e.code, time.perf_counter() - started, attempt > 0
        except (urllib.error.URLError, ConnectionError, TimeoutError, OSError):
            if attempt == 1:
                return None, time.perf_counter() - started, True
    raise AssertionError("unreachable")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("url")
    parser.add_argument("--seconds", type=float, default=20)
    parser.add_argument("--threads", type=int, default=8)
    parser.add_argument("--event", action="append", default=[], help="T:COMMAND")
    args = parser.parse_args()
    url = args.url.rstrip("/")
    stop = time.monotonic() + args.seconds
    lock = threading.Lock()
    statuses, latencies, retried = {}, [], [0]

    def client():
        while time.monotonic() < stop:
            status, seconds, was_retried = one_request(url)
            with lock:
                key = str(status) if status is not None else "no_answer"
                statuses[key] = statuses.get(key, 0) + 1
                latencies.append(seconds)
                retried[0] += was_retried

    threads = [threading.Thread(target=client) for _ in range(args.threads)]
    start = time.monotonic()
    for t in threads:
        t.start()
    events = []
    for spec in args.event:
        at, command = spec.split(":", 1)
        events.append((float(at), command))
    for at, command in sorted(events):
        time.sleep(max(0.0, start + at - time.monotonic()))
        done = subprocess.run(command, shell=True, capture_output=True, text=True)
        print(f"t = {time.monotonic() - start:5.1f} s: {command} (exit {done.returncode})", file=sys.stderr)
    for t in threads:
        t.join()
    elapsed = time.monotonic() - start
    latencies.sort()
    total = len(latencies)
    pct = lambda q: round(1000 * latencies[min(total - 1, int(q * total))], 1) if total else None
    server_errors = sum(v for k, v in statuses.items() if k.startswith("5"))
    report = {
        "requests": total,
        "per_second": round(total / elapsed, 1),
        "statuses": statuses,
        "retried_after_connection_error": retried[0],
        "unanswered": statuses.get("no_answer", 0),
        "server_errors": server_errors,
        "p50_ms": pct(0.50),
        "p99_ms": pct(0.99),
        "max_ms": round(1000 * latencies[-1], 1) if total else None,
    }
    print(json.dumps(report))
    sys.exit(1 if report["unanswered"] or server_errors or not total else 0)


if __name__ == "__main__":
    main()
