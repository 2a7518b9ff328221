#!/usr/bin/env bash
# examples/docker_check.sh: the Dockerfile's steps run outside Docker (no
# engine runs on this kind of machine), on a clean checkout of HEAD, so
# that the image's recipe fails loudly when it drifts from the code: the
# build stage's WORKDIR and RUN lines in a fresh clone (COPY . .), the
# final stage's COPY --from=build source found where the build put it, and
# its CMD run. The clone's build directory is kept in target/docker-check
# between runs (CARGO_TARGET_DIR; DOCKER_CHECK_TARGET_DIR puts it
# elsewhere), the one difference from `docker build`.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
w=$(mktemp -d)
trap 'rm -rf "$w"' EXIT
git clone --quiet "$root" "$w/src"
export CARGO_TARGET_DIR=${DOCKER_CHECK_TARGET_DIR:-$root/target/docker-check}
python3 - "$root/Dockerfile" "$w" <<'PY'
import json, os, re, shlex, subprocess, sys
dockerfile, w = sys.argv[1], sys.argv[2]
src = os.path.join(w, "src")
target = os.environ["CARGO_TARGET_DIR"]
stage, workdir, ran, copied, cmd = None, None, 0, 0, None
def local(path):
    """A path of the build stage's filesystem, outside Docker."""
    if workdir and path.startswith(workdir + "/target/"):
        return os.path.join(target, path[len(workdir + "/target/"):])
    if workdir and path.startswith(workdir):
        return os.path.join(src, path[len(workdir):].lstrip("/"))
    return path
for line in open(dockerfile):
    line = line.strip()
    if not line or line.startswith("#"):
        continue
    op, _, arg = line.partition(" ")
    if op == "FROM":
        stage = arg.split(" AS ")[-1] if " AS " in arg else arg
    elif op == "WORKDIR" and stage == "build":
        workdir = arg
    elif op == "COPY" and stage == "build":
        assert arg == ". .", f"the build stage copies {arg!r}: this check clones the checkout for '. .'"
    elif op == "RUN" and stage == "build":
        print(f"RUN {arg}", flush=True)
        subprocess.run(arg, shell=True, cwd=src, check=True)
        ran += 1
    elif op == "COPY" and arg.startswith("--from=build "):
        source = arg.split()[1]
        assert os.path.isfile(local(source)), f"COPY --from=build {source}: the build made no such file"
        copied += 1
        binary = local(source)
    elif op == "CMD":
        cmd = json.loads(arg)
assert ran and copied and cmd, (ran, copied, cmd)
name = os.path.basename(binary)
assert cmd[0] == name, f"CMD runs {cmd[0]}, the image holds {name}"
subprocess.run([binary] + cmd[1:], check=True, stdout=subprocess.DEVNULL)
print(f"Dockerfile: {ran} build step(s) on a clean checkout, the binary copied from where the build put it, CMD {' '.join(cmd)} runs")
PY
