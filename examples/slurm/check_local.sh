#!/usr/bin/env bash
# examples/slurm/check_local.sh: rd_array.sh on a real one-node Slurm, end
# to end. As root on a Debian 12 machine without systemd: installs
# Debian's slurmctld, slurmd, slurm-client and munge, starts munged,
# slurmctld and slurmd by hand (proctrack/linuxproc, task/none, no
# cgroups, the node's memory declared since the script asks for --mem),
# runs a small study as a 3-task array, kills task 2 mid-run, reruns that
# index alone (sbatch --array=2), merges, and compares the merge with the
# unsharded `mocomp rd` row for row (times and shard apart); then stops
# every daemon it started, by its PID. MOCOMP: the binary (default
# target/release/mocomp). Exit 0 when every check holds.
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$PWD
mocomp=$(realpath "${MOCOMP:-target/release/mocomp}")
[ -x "$mocomp" ] || { echo "no mocomp binary at $mocomp (cargo build --release, or MOCOMP=...)" >&2; exit 2; }
[ "$(id -u)" = 0 ] || { echo "run as root (it installs and starts the Slurm daemons)" >&2; exit 2; }

need=()
for p in slurmctld slurmd slurm-client munge; do dpkg -s "$p" >/dev/null 2>&1 || need+=("$p"); done
if [ ${#need[@]} -gt 0 ]; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq >/dev/null
  apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi

w=$(mktemp -d /tmp/mocomp-slurm.XXXXXX)
chmod 755 "$w"
pids=()
stop() {
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  [ -f "$w/munged.pid" ] && kill "$(cat "$w/munged.pid")" 2>/dev/null || true
  sleep 1
  for pid in "${pids[@]}"; do kill -9 "$pid" 2>/dev/null || true; done
}
trap stop EXIT

# munge: a key of our own, its socket and state under $w.
mkdir -p "$w/munge"
dd if=/dev/urandom of="$w/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$w/munge/munge.key"
/usr/sbin/munged --force --key-file="$w/munge/munge.key" --socket="$w/munge/socket" \
  --pid-file="$w/munged.pid" --log-file="$w/munged.log" --seed-file="$w/munge/seed"
for _ in $(seq 50); do [ -S "$w/munge/socket" ] && break; sleep 0.1; done

host=$(hostname -s)
mem=$(awk '/MemTotal/ {print int($2 / 1024 * 0.8)}' /proc/meminfo)
mkdir -p "$w/state" "$w/spool"
cat >"$w/slurm.conf" <<EOF
ClusterName=mocompcheck
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$w/munge/socket
CredType=cred/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
StateSaveLocation=$w/state
SlurmdSpoolDir=$w/spool
SlurmctldPidFile=$w/slurmctld.pid
SlurmdPidFile=$w/slurmd.pid
SlurmctldLogFile=$w/slurmctld.log
SlurmdLogFile=$w/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
NodeName=$host CPUs=$(nproc) RealMemory=$mem State=UNKNOWN
PartitionName=check Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$w/slurm.conf
slurmctld -D -i >"$w/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D >"$w/slurmd.out" 2>&1 &
pids+=($!)
for _ in $(seq 100); do
  sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix)' && break
  sleep 0.2
done
sinfo -h -o '%P %t %c' | grep -qE 'idle|mix' || { tail -20 "$w"/slurm*.log >&2; echo "the node did not come up" >&2; exit 1; }

# The study: two sequences, two predictors, two QPs, 3 shards; task 2's
# share is slow enough (exhaustive search over the slow preset's range
# of 32, 20 frames) to be killed mid-run.
mkdir -p "$w/seqs" "$w/out"
cp samples/tree_qcif.y4m samples/synth_qcif.y4m "$w/seqs/"
export MOCOMP=$mocomp PREDICTORS="zero,block:esa" QPS="27,37" RD_ARGS="--frames 20 --preset slow"
cd "$w"
wait_job() { while squeue -h -j "$1" 2>/dev/null | grep -q .; do sleep 0.5; done; }
"$mocomp" rd seqs/*.y4m --predictors "$PREDICTORS" --qp "$QPS" --threads 2 -o whole.csv $RD_ARGS
job=$(sbatch --parsable --array=1-3 "$root/examples/slurm/rd_array.sh" seqs out 3)
# Kill task 2 once it has written one row.
for _ in $(seq 600); do
  [ "$( (wc -l <out/part_2.csv) 2>/dev/null || echo 0)" -ge 2 ] && break
  sleep 0.2
done
scancel "${job}_2"
wait_job "$job"
rows_killed=$(($(wc -l <out/part_2.csv) - 1))
sum() { md5sum out/part_1.csv out/part_3.csv; }
before=$(sum)
rerun=$(sbatch --parsable --array=2 "$root/examples/slurm/rd_array.sh" seqs out 3)
wait_job "$rerun"
after=$(sum)
[ "$before" = "$after" ] || { echo "the rerun of task 2 touched another shard's part" >&2; exit 1; }
grep -q "of the .* jobs of shard 2/3 are there already" out/logs/part_2.log \
  || { cat out/logs/part_2.log >&2; echo "the rerun did not resume shard 2/3" >&2; exit 1; }
"$mocomp" rd merge out/part_*.csv -o out/rd.csv --quiet
python3 - whole.csv out/rd.csv <<'EOF'
import csv, sys
def rows(path):
    r = list(csv.DictReader(open(path)))
    return [{k: v for k, v in row.items() if k not in ("encode_ms", "me_ms", "decode_ms", "shard")} for row in r]
a, b = rows(sys.argv[1]), rows(sys.argv[2])
assert len(a) == len(b) == 8, (len(a), len(b))
assert a == b, "the merged study differs from the unsharded one"
EOF
echo "one-node Slurm 22.05: 3-task array, task 2 killed after $rows_killed of its rows, rerun alone (--array=2):"
echo "  the other parts untouched, the merge equal to the unsharded study row for row (8 jobs)"
