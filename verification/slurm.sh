#!/usr/bin/env bash
# Slurm backend of `ncform sweep` on a one-node Slurm cluster started here.
#
#   bash verification/slurm.sh [--ncform PATH] [--cluster-only] [--keep-logs]
#
# 1. installs Debian's slurm-wlm and munge when missing (apt-get), starts
#    munged, slurmctld and slurmd from a temporary folder (everything on the
#    loopback, config written here, nothing in /etc touched),
# 2. takes the ncform binary from --ncform PATH or target/release/ncform
#    (builds nothing),
# 3. runs a small sweep through `ncform sweep ... --slurm` (submitted held),
#    cancels its last array task (scancel JOBID_TASK), releases it, waits,
#    resumes with
#    `ncform sweep DIR --resume --slurm`, waits, `--status`, `collect`,
# 4. runs the same sweep locally (--jobs 1) and compares each point's final
#    force (1e-9 relative) and that every point is complete,
# 5. prints PASS/FAIL lines, the elapsed seconds of the Slurm and the local
#    path, and one final "CHECK-SUMMARY passed=N failed=M" line.
# --cluster-only stops after a one-task test array job (daemons + sbatch).
# The daemons started here are stopped by their PIDs on exit and the
# temporary folder is removed (kept with --keep-logs).
#
# What the config needs, and why (Slurm 22.05, Debian 12, no systemd):
# - ProctrackType=proctrack/pgid, TaskPlugin=task/none,
#   JobAcctGatherType=jobacct_gather/none: no cgroup plugin is needed to run
#   or track jobs, so slurmd works without systemd or a delegated cgroup tree;
# - cgroup.conf beside slurm.conf with CgroupPlugin=autodetect and
#   IgnoreSystemd=yes (22.05 has no CgroupPlugin=disabled; IgnoreSystemd is
#   its documented option for cgroup v2 without systemd): meant for a cgroup
#   v2 host, where slurmd's cgroup/v2 plugin would otherwise ask systemd
#   (dbus) for its scope. Not exercised here: this host mounts cgroup v1
#   (hybrid), and with the plugins above slurmd loads no cgroup plugin and
#   runs without any cgroup.conf as well;
# - AuthType=auth/munge with AuthInfo=socket=<temp>/munge.socket: munged runs
#   from the temporary folder, not from /run/munge;
# - AccountingStorageType=accounting_storage/none: no slurmdbd, so `sacct`
#   has no data; the backend then treats "not in squeue" as "not running".
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/.." && pwd)"
ncform="$repo/target/release/ncform"
cluster_only=0
keep=0
while [ $# -gt 0 ]; do
    case "$1" in
        --ncform) ncform="$2"; shift 2 ;;
        --cluster-only) cluster_only=1; shift ;;
        --keep-logs) keep=1; shift ;;
        *) echo "usage: $0 [--ncform PATH] [--cluster-only] [--keep-logs]" >&2; exit 2 ;;
    esac
done

passed=0
failed=0
check() { # check NAME OK DETAIL
    if [ "$2" -eq 1 ]; then
        echo "PASS [slurm] $1: $3"
        passed=$((passed + 1))
    else
        echo "FAIL [slurm] $1: $3"
        failed=$((failed + 1))
    fi
}
summarised=0
summary() {
    echo "CHECK-SUMMARY passed=$passed failed=$failed"
    summarised=1
}

# --- 1. Slurm and munge -------------------------------------------------------
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null \
    || ! command -v sbatch >/dev/null || ! command -v munged >/dev/null; then
    echo "# installing slurm-wlm and munge (apt-get)"
    if ! { apt-get update -qq && DEBIAN_FRONTEND=noninteractive \
        apt-get install -y -qq slurm-wlm munge >/dev/null; }; then
        check install 0 "apt-get install slurm-wlm munge failed"
        summary
        exit 1
    fi
fi
check install 1 "$(slurmd -V), $(munged --version 2>&1 | head -n 1)"

tmp="$(mktemp -d /tmp/ncform-slurm.XXXXXX)"
chmod 755 "$tmp"
pids=()
cleanup() {
    local rc=$? pid
    if [ "$summarised" -eq 0 ]; then
        check script 0 "stopped early (exit status $rc)"
        summary
    fi
    for pid in "${pids[@]}"; do
        kill "$pid" 2>/dev/null || true
    done
    for pid in "${pids[@]}"; do
        for _ in $(seq 50); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.1
        done
        kill -9 "$pid" 2>/dev/null || true
    done
    if [ "$keep" -eq 1 ]; then
        echo "# kept $tmp"
    else
        rm -rf "$tmp"
    fi
}
trap cleanup EXIT

# munged: key, socket, pid and log in the temporary folder.
mkdir -p "$tmp/munge"
chmod 700 "$tmp/munge"
mungekey --create --keyfile="$tmp/munge/munge.key" 2>/dev/null \
    || dd if=/dev/urandom of="$tmp/munge/munge.key" bs=1024 count=1 status=none
chmod 600 "$tmp/munge/munge.key"
socket="$tmp/munge/munge.socket"
munged --foreground --force --socket="$socket" --key-file="$tmp/munge/munge.key" \
    --pid-file="$tmp/munge/munged.pid" --log-file="$tmp/munge/munged.log" \
    --seed-file="$tmp/munge/munged.seed" >"$tmp/munge/munged.out" 2>&1 &
pids+=("$!")
for _ in $(seq 50); do
    [ -S "$socket" ] && break
    sleep 0.1
done
if ! [ -S "$socket" ]; then
    check munged 0 "no socket after 5 s"
    cat "$tmp/munge/munged.out" "$tmp/munge/munged.log" 2>/dev/null || true
    summary
    exit 1
fi

# slurm.conf and cgroup.conf.
cpus="$(nproc)"
mem_mb="$(awk '/MemTotal/ {print int($2 / 1024 * 0.8)}' /proc/meminfo)"
mkdir -p "$tmp/state" "$tmp/spool" "$tmp/log"
conf="$tmp/slurm.conf"
cat >"$conf" <<EOF
ClusterName=ncform
SlurmctldHost=localhost
SlurmctldPort=$((6817 + RANDOM % 1000 * 2))
SlurmdPort=$((7817 + RANDOM % 1000 * 2))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket
MpiDefault=none
MailProg=/bin/true
ProctrackType=proctrack/pgid
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SlurmctldPidFile=$tmp/state/slurmctld.pid
SlurmdPidFile=$tmp/state/slurmd.pid
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ReturnToService=2
SchedulerType=sched/backfill
SchedulerParameters=sched_interval=1
MinJobAge=30
KillWait=5
InactiveLimit=0
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
cat >"$tmp/cgroup.conf" <<EOF
CgroupPlugin=autodetect
IgnoreSystemd=yes
EOF
export SLURM_CONF="$conf"

slurmctld -D -i -f "$conf" >"$tmp/log/slurmctld.out" 2>&1 &
pids+=("$!")
slurmd -D -f "$conf" >"$tmp/log/slurmd.out" 2>&1 &
pids+=("$!")

print_logs() {
    local f
    for f in "$tmp"/log/*; do
        echo "# --- $f"
        tail -n 40 "$f" || true
    done
}
state=""
t0=$SECONDS
while [ $((SECONDS - t0)) -lt 60 ]; do
    state="$(sinfo -h -o %T 2>/dev/null | head -n 1 || true)"
    [ "$state" = "idle" ] && break
    sleep 1
done
if [ "$state" = "idle" ]; then
    check daemons 1 "slurmctld and slurmd up, node idle after $((SECONDS - t0)) s"
else
    check daemons 0 "node not idle after 60 s (sinfo: '${state}')"
    print_logs
    summary
    exit 1
fi

# A one-task test array job: sbatch, squeue, the job's output.
cat >"$tmp/hello.sh" <<EOF
#!/bin/bash
#SBATCH --job-name=ncform-hello
#SBATCH --array=0-1
#SBATCH --output=$tmp/hello_%A_%a.out
echo "hello \$SLURM_ARRAY_TASK_ID"
EOF
job="$(sbatch --parsable "$tmp/hello.sh")"
job="${job%%;*}"
t0=$SECONDS
while [ $((SECONDS - t0)) -lt 60 ] && [ -n "$(squeue -h -j "$job" 2>/dev/null)" ]; do
    sleep 0.5
done
if grep -qx "hello 1" "$tmp/hello_${job}_1.out" 2>/dev/null; then
    check hello 1 "array job $job ran (hello_${job}_1.out) in $((SECONDS - t0)) s"
else
    check hello 0 "array job $job did not write hello_${job}_1.out"
    print_logs
fi
if [ "$cluster_only" -eq 1 ]; then
    summary
    [ "$failed" -eq 0 ]
    exit
fi

# --- 2. The binary ------------------------------------------------------------
if ! [ -x "$ncform" ]; then
    check binary 0 "no ncform binary at $ncform (build it: cargo build --release --bin ncform)"
    summary
    exit 1
fi
ncform="$(cd "$(dirname "$ncform")" && pwd)/$(basename "$ncform")"

# --- 3. A small sweep through Slurm -------------------------------------------
sweep="$repo/cases/sweeps/oat45-quick.toml"
if ! [ -f "$sweep" ]; then
    sweep="$tmp/oat45-quick.toml"
    cat >"$sweep" <<TOML
# Coarse 45° off-axis tension tests at three clamp displacements.
case = "$repo/cases/oat45.toml"
design = "grid"

[[vary]]
key = "loading.displacement"
values = [10.0, 20.0, 30.0]

[[set]]
key = "mesh.element_size"
value = 10.0
TOML
fi
echo "# sweep file $sweep"
dir="$tmp/sweep-slurm"
dir2="$tmp/sweep-local"
log="$tmp/log"

# The points' completion from their status.json (the sweep's truth).
point_report() { # point_report DIR -> lines "NNNN STATE"
    python3 - "$1" <<'PY'
import json, pathlib, sys
for p in sorted(pathlib.Path(sys.argv[1], "points").iterdir()):
    try:
        s = json.loads((p / "status.json").read_text())
        state = s.get("status", s.get("state", "?")) if isinstance(s, dict) else "?"
    except (OSError, ValueError):
        state = "missing"
    print(p.name, state)
PY
}
# Job ids and tasks of DIR/slurm/submissions.json: lines "JOB NTASKS POINTS-OF-LAST-TASK".
submissions() {
    python3 - "$1" <<'PY'
import json, sys
for s in json.load(open(sys.argv[1] + "/slurm/submissions.json")):
    print(s["job_id"], len(s["tasks"]), ",".join(map(str, s["tasks"][-1])))
PY
}
wait_jobs() { # wait_jobs IDS TIMEOUT: until squeue lists none of them
    local t0=$SECONDS
    while [ $((SECONDS - t0)) -lt "$2" ]; do
        [ -z "$(squeue -h -j "$1" 2>/dev/null || true)" ] && return 0
        sleep 1
    done
    return 1
}

t_slurm=$SECONDS
set +e
# Submitted held (--hold), so that the last task is surely still pending when
# it is cancelled (a coarse point takes well under a second); then released.
"$ncform" sweep "$sweep" --out "$dir" --slurm --max-parallel 1 --sbatch-arg=--hold \
    >"$log.submit" 2>&1
rc=$?
set -e
cat "$log.submit"
submitted="$(grep -E '^Submitted batch job [0-9]+' "$log.submit" | head -n 1 || true)"
if [ "$rc" -eq 0 ] && [ -n "$submitted" ] && [ -f "$dir/slurm/submissions.json" ]; then
    check submit 1 "ncform sweep --slurm: $submitted"
else
    check submit 0 "ncform sweep --slurm exited $rc (submitted line: '${submitted}')"
    print_logs
    summary
    exit 1
fi
read -r job ntasks last_points < <(submissions "$dir" | tail -n 1) || true
last=$((ntasks - 1))
state="$(squeue -h -r -j "$job" -o '%i %T' 2>/dev/null | awk -v t="${job}_${last}" '$1 == t {print $2}')"
if scancel "${job}_${last}"; then
    check scancel 1 "cancelled task ${job}_${last} (points $last_points) while ${state:-gone}"
else
    check scancel 0 "scancel ${job}_${last} failed"
fi
scontrol release "$job" || true
if wait_jobs "$job" 900; then
    check first-pass 1 "job $job left the queue after $((SECONDS - t_slurm)) s"
else
    check first-pass 0 "job $job still queued after 900 s"
    squeue -j "$job" || true
fi
echo "# after the first pass (status.json of each point):"
point_report "$dir"
set +e
"$ncform" sweep "$dir" --status
set -e

# Resume: only the cancelled task's points go again.
set +e
"$ncform" sweep "$dir" --resume --slurm >"$log.resume" 2>&1
rc=$?
set -e
cat "$log.resume"
read -r job2 _ points2 < <(submissions "$dir" | tail -n 1) || true
if [ "$rc" -eq 0 ] && [ "$job2" != "$job" ]; then
    check resume 1 "--resume --slurm resubmitted points $points2 as job $job2"
else
    check resume 0 "--resume --slurm exited $rc, last job $job2 (first $job)"
fi
if [ "$(submissions "$dir" | wc -l)" -eq 2 ] && [ "$points2" = "$last_points" ]; then
    check resume-points 1 "only the cancelled points ($last_points) were resubmitted"
else
    check resume-points 0 "resubmitted: $(submissions "$dir" | tail -n +2 | tr '\n' ';'), cancelled: $last_points"
fi
scontrol release "$job2" 2>/dev/null || true # in case --resume reused --hold
if wait_jobs "$job2" 900; then
    check second-pass 1 "job $job2 left the queue"
else
    check second-pass 0 "job $job2 still queued after 900 s"
fi
t_slurm=$((SECONDS - t_slurm))
set +e
"$ncform" sweep "$dir" --status
rc_status=$?
"$ncform" collect "$dir"
rc_collect=$?
set -e
check status "$([ "$rc_status" -eq 0 ] && echo 1 || echo 0)" "ncform sweep DIR --status exited $rc_status"
check collect "$([ "$rc_collect" -eq 0 ] && [ -f "$dir/results.csv" ] && echo 1 || echo 0)" \
    "ncform collect DIR exited $rc_collect, results.csv $([ -f "$dir/results.csv" ] && echo written || echo missing)"
incomplete="$(point_report "$dir" | awk '$2 != "complete"' | tr '\n' ';')"
check complete "$([ -z "$incomplete" ] && echo 1 || echo 0)" \
    "every point complete after the resume${incomplete:+ (not: $incomplete)}"
for f in "$dir"/slurm/*.out; do
    if grep -qiE 'error|panic' "$f"; then
        echo "# --- $f"
        cat "$f"
    fi
done

# --- 4. The same sweep locally ------------------------------------------------
t_local=$SECONDS
set +e
"$ncform" sweep "$sweep" --out "$dir2" --jobs 1 >"$log.local" 2>&1
rc=$?
set -e
t_local=$((SECONDS - t_local))
tail -n 20 "$log.local"
check local "$([ "$rc" -eq 0 ] && echo 1 || echo 0)" "ncform sweep --jobs 1 exited $rc in $t_local s"
if ! [ -f "$dir2/results.csv" ]; then
    "$ncform" collect "$dir2" >/dev/null 2>&1 || true
fi
set +e
cmp_out="$(python3 - "$dir/results.csv" "$dir2/results.csv" <<'PY'
import csv, sys
def read(path):  # results.csv: "#" comment lines, then a header
    with open(path, newline="") as f:
        return list(csv.DictReader(l for l in f if not l.startswith("#")))
a, b = read(sys.argv[1]), read(sys.argv[2])
fields = list(a[0].keys()) if a else []
cols = [c for c in fields if "force" in c.lower()]
key = "point" if "point" in fields else None
if not a or len(a) != len(b) or not cols:
    print(f"rows {len(a)} vs {len(b)}, force columns {cols}")
    sys.exit(1)
ka = {r[key] if key else str(i): r for i, r in enumerate(a)}
kb = {r[key] if key else str(i): r for i, r in enumerate(b)}
worst, bad = 0.0, []
for k, ra in ka.items():
    rb = kb.get(k) or {}
    for r, where in ((ra, "slurm"), (rb, "local")):
        if "status" in r and r["status"] != "complete":
            bad.append(f"{k}: {where} status {r['status']}")
    for c in cols:
        x, y = ra.get(c) or "", rb.get(c) or ""
        if x == "" and y == "":
            continue  # no value in either (e.g. a force at a displacement not reached)
        try:
            x, y = float(x), float(y)
        except ValueError:
            bad.append(f"{k}:{c} {x!r} vs {y!r}")
            continue
        rel = abs(x - y) / max(abs(x), abs(y), 1e-300)
        worst = max(worst, rel) if rel == rel else float("inf")
        if not rel <= 1e-9:
            bad.append(f"{k}:{c} {x} vs {y}")
print(f"{len(ka)} points, columns {cols}, largest relative difference {worst:.3g}"
      + (f"; differ: {bad}" if bad else ""))
sys.exit(1 if bad else 0)
PY
)"
rc=$?
set -e
check forces "$([ "$rc" -eq 0 ] && echo 1 || echo 0)" "Slurm vs local results.csv: $cmp_out"

# --- 5. Overhead and summary ----------------------------------------------------
echo "# elapsed: Slurm path ${t_slurm} s (submit, first pass with one task cancelled, resume, second pass), local path ${t_local} s (--jobs 1)"
summary
[ "$failed" -eq 0 ]
