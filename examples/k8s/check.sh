#!/usr/bin/env bash
# examples/k8s/check.sh: rd-job.yaml checked as far as a machine without a
# cluster allows, so that it fails loudly when it drifts from the code:
# 1. the manifest against Kubernetes' own schemas (kubernetes-validate
#    --strict, from PyPI, into target/k8s-venv; unknown fields refused),
#    for 1.33 (backoffLimitPerIndex's GA) and the newest it knows;
# 2. its shard count: completions, parallelism and the command's "/N" agree;
# 3. the pod's command itself, run by sh for index 0 with /data a
#    temporary folder holding the bundled samples and `mocomp` this
#    checkout's binary (MOCOMP, default target/release/mocomp): it must
#    write part_1.csv with its shard's rows.
set -euo pipefail
cd "$(dirname "$0")/../.."
manifest=examples/k8s/rd-job.yaml
venv=target/k8s-venv
[ -x "$venv/bin/kubernetes-validate" ] || {
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --disable-pip-version-check "kubernetes-validate==1.37.0"
}
for v in 1.33.0 1.37.0; do
  "$venv/bin/kubernetes-validate" --strict --quiet -k "$v" "$manifest"
done
"$venv/bin/python" - "$manifest" <<'PY'
import re, sys, yaml
job = yaml.safe_load(open(sys.argv[1]))
spec = job["spec"]
cmd = " ".join(spec["template"]["spec"]["containers"][0]["args"])
shards = {int(n) for n in re.findall(r"/(\d+)\b", cmd) if "shard" in cmd}
assert spec["completionMode"] == "Indexed", spec["completionMode"]
assert shards == {spec["completions"]} == {spec["parallelism"]}, (shards, spec["completions"], spec["parallelism"])
open("target/k8s-command.sh", "w").write(cmd + "\n")
PY
mocomp=$(realpath "${MOCOMP:-target/release/mocomp}")
[ -x "$mocomp" ] || { echo "no mocomp binary at $mocomp (cargo build --release, or MOCOMP=...)" >&2; exit 2; }
data=$(mktemp -d)
trap 'rm -rf "$data"' EXIT
mkdir -p "$data/seqs" "$data/bin"
cp samples/tree_qcif.y4m samples/synth_qcif.y4m "$data/seqs/"
ln -s "$mocomp" "$data/bin/mocomp"
sed "s|/data|$data|g" target/k8s-command.sh >"$data/command.sh"
(cd "$data" && PATH="$data/bin:$PATH" JOB_COMPLETION_INDEX=0 sh "$data/command.sh" >/dev/null)
rows=$(($(wc -l <"$data/out/part_1.csv") - 1))
[ "$rows" -ge 1 ] || { echo "the pod's command wrote no row" >&2; exit 1; }
grep -q ",1/16$" "$data/out/part_1.csv" || { echo "part_1.csv's rows are not of shard 1/16" >&2; exit 1; }
echo "rd-job.yaml: schema-valid for Kubernetes 1.33 and 1.37, 16 shards throughout, pod 0's command wrote $rows rows of shard 1/16"
