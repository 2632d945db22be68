# Shared by scripts/container-test and scripts/container/failover-test
# (sourced, from the repository root): where they work, their ports, and
# the helpers both use. NAME (the caller's name, for `fail`) must be set.
IMAGE=${IMAGE:-${TREEMANIP_IMAGE:-localhost/treemanip:latest}}
WORK=${TREEMANIP_CONTAINER_WORK:-/var/tmp/treemanip-container}
PORT=18080
LB_PORT=18090
mkdir -p "$WORK"

step() { printf '\n== %s\n' "$*" >&2; }
now() { date +%s.%N; }
elapsed() { python3 -c "print(f'{$2 - $1:.2f}')"; }
fail() { echo "$NAME: FAIL: $*" >&2; exit 1; }
cleanup() {
    podman rm -f --ignore treemanip-test treemanip-r1 treemanip-r2 treemanip-r3 >/dev/null 2>&1 || true
    [[ -n "${HAPROXY_PID:-}" ]] && kill "$HAPROXY_PID" 2>/dev/null || true
}
wait_ready() { # URL, seconds → prints seconds waited
    local url=$1 limit=$2 t0
    t0=$(now)
    until curl -fsS -o /dev/null "$url/readyz" 2>/dev/null; do
        if [[ $(elapsed "$t0" "$(now)" | cut -d. -f1) -ge $limit ]]; then return 1; fi
        sleep 0.02
    done
    elapsed "$t0" "$(now)"
}
