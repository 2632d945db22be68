#!/usr/bin/env python3
"""One slow POST /v1/plan through a load balancer while the replica
computing it is killed: the answer must still be 200, and the same plan
another replica gives directly (timing fields aside).

The client sends the request's headers, then its body 0.1 s later, as a
client on a slow link (or any client whose body leaves in a second packet)
does: a load balancer that passes the request on before it has the whole
body cannot replay it, and answers 502 when the replica dies (what issue 33
found in HAProxy's log: `SH--`, no retry).

Usage: slow-plan.py LB_URL DIRECT_URL --kill-after 0.5 --kill 'podman kill -s KILL r1'
Prints a JSON summary; exit 1 when the plan was lost or differs.
"""

import argparse
import http.client
import json
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request

TIMING = {"total_ms", "ms"}


def tree(nodes=30, seed=4, url=None):
    with urllib.request.urlopen(f"{url}/v1/trees/example?nodes={nodes}&seed={seed}", timeout=10) as r:
        return json.loads(r.read())["tree"]


def post(url, body, timeout=60):
    request = urllib.request.Request(
        url + "/v1/plan", data=json.dumps(body).encode(), headers={"Content-Type": "application/json"}
    )
    started = time.perf_counter()
    try:
        with urllib.request.urlopen(request, timeout=timeout) as r:
            return r.status, json.loads(r.read()), time.perf_counter() - started
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"null"), time.perf_counter() - started


def post_slowly(url, body, pause=0.1, timeout=60):
    """POST /v1/plan: the headers, a pause, then the body."""
    host = url.split("://", 1)[1].rstrip("/")
    data = json.dumps(body).encode()
    started = time.perf_counter()
    conn = http.client.HTTPConnection(host, timeout=timeout)
    conn.putrequest("POST", "/v1/plan")
    conn.putheader("Content-Type", "application/json")
    conn.putheader("Content-Length", str(len(data)))
    conn.endheaders()
    time.sleep(pause)
    conn.send(data)
    response = conn.getresponse()
    text = response.read()
    conn.close()
    try:
        answer = json.loads(text)
    except ValueError:
        answer = text.decode(errors="replace")
    return response.status, answer, time.perf_counter() - started


def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items() if k not in TIMING}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("lb")
    parser.add_argument("direct")
    parser.add_argument("--kill-after", type=float, default=0.5)
    parser.add_argument("--kill", required=True)
    args = parser.parse_args()
    t = tree(url=args.direct)
    target = [[p[0] + 0.02 * (k % 3), p[1] + 0.03, p[2]] for k, p in enumerate(t["positions"])]
    target[0] = t["positions"][0]
    # The forward model scoring pushes of every node (29 candidates), a base
    # region, the largest budgets: about 1.5 s on a 2-core machine.
    body = {
        "tree": t,
        "target_positions": target,
        "strategy": "model",
        "max_candidates": 29,
        "robot": {"base_region": {"min": [-1, -0.5, 0.1], "max": [0, 0.5, 1]}},
        "max_evaluations": 512,
        "budget_ms": 5000,
        "seed": 3,
        "allow_out_of_domain": True,
    }
    result = {}

    def send():
        result["status"], result["answer"], result["seconds"] = post_slowly(args.lb, body)

    client = threading.Thread(target=send)
    client.start()
    time.sleep(0.1 + args.kill_after)  # the body's pause, then into the plan
    killed = subprocess.run(args.kill, shell=True, capture_output=True, text=True)
    client.join()
    direct_status, direct, direct_seconds = post(args.direct, body)
    same = result["status"] == 200 and direct_status == 200 and strip(result["answer"]) == strip(direct)
    report = {
        "status": result["status"],
        "seconds": round(result["seconds"], 2),
        "killed_at_s": args.kill_after,
        "kill_exit": killed.returncode,
        "direct_seconds": round(direct_seconds, 2),
        "same_plan_as_direct": same,
    }
    if result["status"] != 200:
        report["answer"] = result["answer"]
    print(json.dumps(report))
    sys.exit(0 if same and killed.returncode == 0 and direct_seconds > args.kill_after else 1)


if __name__ == "__main__":
    main()
