#!/usr/bin/env bash
# A photonlm bake split over a Slurm cluster (docs/farm.md):
#
#   scripts/slurm_bake.sh SCENE.json -o OUT_DIR --shards N [--texel-ranges M] [--partition P] [--time T]
#                         [--photons N] [--seed S] [--threads T] [--retries R] [--photonlm PATH] [--wait]
#                         [--target-error X [--max-rounds R]]
#
# Submits the N shards as one job array (`photonlm bake SCENE --shard K/N -o OUT_DIR/parts`)
# and the merge (`photonlm merge OUT_DIR/parts -o OUT_DIR`) as a job that starts once every
# shard has ended (afterany): the merge itself refuses, naming the shard, when a part is
# missing or does not belong, so a lost shard fails the merge cleanly. A shard that fails is
# requeued (scontrol requeue) up to R times (default 2). Part files are written to a temporary
# name and renamed, and the merge reads only *.plmpart files, so nothing half-written is read.
# With --texel-ranges M the direct pass runs as a second array of M tasks beside the shards
# (`photonlm bake SCENE --direct K/M`, it needs no photons) and the final gather as a third
# that starts once both have succeeded (afterok; `photonlm bake SCENE --gather K/M`, reading
# the parts); the merge then joins them. A task of either is requeued like a shard.
# OUT_DIR, the scene (and the files it names) and photonlm must be on a filesystem every
# node sees at the same path. Prints the two job ids; --wait blocks until the merge ends and
# exits with its status. The result is bit for bit `photonlm bake SCENE -o OUT_DIR`.
# --target-error X bakes in rounds (and waits): after each merge, report.json says whether the
# error estimate met X; if not, the next round bakes again with the photons 1 / sqrt(photons)
# predicts (earlier rounds' photons are not reused), at most R rounds (default 4); exit 3 if
# the target is not met.
set -euo pipefail

usage() {
  sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 1
}

scene="" out="" shards="" ranges=0 partition="" time_limit="" photons="" seed="" threads="" retries=2 wait=0 target=""
max_rounds=4
photonlm="${PHOTONLM:-}"
while [ $# -gt 0 ]; do
  case "$1" in
    -o|--out) out="$2"; shift 2 ;;
    --shards) shards="$2"; shift 2 ;;
    --texel-ranges) ranges="$2"; shift 2 ;;
    --partition) partition="$2"; shift 2 ;;
    --time) time_limit="$2"; shift 2 ;;
    --photons) photons="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --retries) retries="$2"; shift 2 ;;
    --photonlm) photonlm="$2"; shift 2 ;;
    --wait) wait=1; shift ;;
    --target-error) target="$2"; shift 2 ;;
    --max-rounds) max_rounds="$2"; shift 2 ;;
    -h|--help) usage ;;
    -*) echo "slurm_bake: unknown option $1" >&2; usage ;;
    *) [ -z "$scene" ] || { echo "slurm_bake: more than one scene ($scene, $1)" >&2; exit 1; }
       scene="$1"; shift ;;
  esac
done
[ -n "$scene" ] && [ -n "$out" ] && [ -n "$shards" ] || usage
[[ "$shards" =~ ^[1-9][0-9]*$ ]] || { echo "slurm_bake: --shards '$shards' is not an integer >= 1" >&2; exit 1; }
[[ "$ranges" =~ ^[0-9]+$ ]] || { echo "slurm_bake: --texel-ranges '$ranges' is not an integer >= 0" >&2; exit 1; }
[[ "$retries" =~ ^[0-9]+$ ]] || { echo "slurm_bake: --retries '$retries' is not an integer >= 0" >&2; exit 1; }
[ -f "$scene" ] || { echo "slurm_bake: $scene: no such scene file" >&2; exit 1; }
command -v sbatch > /dev/null || { echo "slurm_bake: sbatch not found: is this a Slurm login node?" >&2; exit 1; }
if [ -z "$photonlm" ]; then
  here="$(cd "$(dirname "$0")/.." && pwd)"
  if [ -x "$here/build/bin/photonlm" ]; then photonlm="$here/build/bin/photonlm"
  else photonlm="$(command -v photonlm || true)"; fi
fi
[ -n "$photonlm" ] && [ -x "$photonlm" ] || { echo "slurm_bake: photonlm not found: give --photonlm PATH" >&2; exit 1; }

# Absolute paths: jobs run elsewhere.
scene="$(cd "$(dirname "$scene")" && pwd)/$(basename "$scene")"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
photonlm="$(cd "$(dirname "$photonlm")" && pwd)/$(basename "$photonlm")"
parts="$out/parts" logs="$out/logs" jobs="$out/jobs"
mkdir -p "$parts" "$logs" "$jobs"
q() { [ $# -eq 0 ] || printf '%q ' "$@"; }

# One sharded bake: writes the job scripts, submits the array and the merge; returns sbatch's
# status for the merge (with --wait: the merge's exit status).
submit_round() {
# Parts of an earlier run (or round) would not merge with this one's; each starts clean.
rm -f "$parts"/*.plmpart "$parts"/*.plmpart.tmp-*
options=()
[ -z "$photons" ] || options+=(--photons "$photons")
[ -z "$seed" ] || options+=(--seed "$seed")
[ -z "$threads" ] || options+=(--threads "$threads")

# One task of an array: STAGE (shard, direct or gather) K = SLURM_ARRAY_TASK_ID of N; on failure
# it requeues itself while SLURM_RESTART_COUNT < retries, else fails. PHOTONLM_TEST_KILL=STAGE:K
# kills that task's first attempt (the retry tests, python_bridge/tests/test_slurm.py).
cat > "$jobs/task.sh" <<EOF
#!/usr/bin/env bash
set -u
stage=\$1 n=\$2
k=\$SLURM_ARRAY_TASK_ID
attempt=\${SLURM_RESTART_COUNT:-0}
case \$stage in
  shard) args=(--shard "\$k/\$n" $(q ${options[@]+"${options[@]}"})) ;;
  direct) args=(--direct "\$k/\$n" $(q ${options[@]+"${options[@]}"}) ${target:+--target-error $target}) ;;
  gather) args=(--gather "\$k/\$n" ${threads:+--threads $threads}) ;;
esac
echo "\$stage \$k of \$n, attempt \$((attempt + 1)) on \$(hostname)"
$(q "$photonlm") bake $(q "$scene") "\${args[@]}" -o $(q "$parts") &
pid=\$!
if [ "\${PHOTONLM_TEST_KILL:-}" = "\$stage:\$k" ] && [ "\$attempt" = 0 ]; then kill -KILL \$pid; fi
wait \$pid
status=\$?
if [ \$status -ne 0 ]; then
  echo "\$stage \$k failed (exit \$status)" >&2
  if [ "\$attempt" -lt $retries ]; then
    echo "requeueing \$stage \$k" >&2
    scontrol requeue "\${SLURM_ARRAY_JOB_ID}_\${k}" && sleep 60
  fi
fi
exit \$status
EOF
cat > "$jobs/merge.sh" <<EOF
#!/usr/bin/env bash
exec $(q "$photonlm") merge $(q "$parts") -o $(q "$out") ${threads:+--threads $threads} ${target:+--target-error $target}
EOF
chmod +x "$jobs/task.sh" "$jobs/merge.sh"

common=()
[ -z "$partition" ] || common+=(--partition "$partition")
[ -z "$time_limit" ] || common+=(--time "$time_limit")
[ -z "$threads" ] || common+=(--cpus-per-task "$threads")
# stage STAGE COUNT [sbatch options]: submits an array of COUNT tasks; prints its job id.
stage() {
  local id
  id=$(sbatch --parsable --job-name="plm-$1" --array="1-$2" --requeue --open-mode=append \
              --output="$logs/$1-%a.log" ${common[@]+"${common[@]}"} "${@:3}" "$jobs/task.sh" "$1" "$2")
  echo "${id%%;*}"
}
array=$(stage shard "$shards")
echo "shards: job array $array (${shards} tasks), parts in $parts"
after="afterany:$array"
if [ "$ranges" -gt 0 ]; then
  # The direct pass needs no photons: it runs beside the shards. The gather needs both; a stage
  # that failed for good cancels it (kill-on-invalid-dep) and the merge says what is missing.
  direct=$(stage direct "$ranges")
  gather=$(stage gather "$ranges" --dependency="afterok:$array:$direct" --kill-on-invalid-dep=yes)
  echo "texel ranges: direct pass job array $direct, final gather job array $gather (${ranges} tasks each)"
  after="afterany:$array:$direct:$gather"
fi
merge_args=(--parsable --job-name=plm-merge --dependency="$after" --output="$logs/merge.log" ${common[@]+"${common[@]}"})
[ "$wait" = 0 ] || merge_args+=(--wait)
set +e
merge=$(sbatch "${merge_args[@]}" "$jobs/merge.sh")
status=$?
set -e
echo "merge: job ${merge%%;*} -> $out (logs in $logs)"
return $status
}

if [ -z "$target" ]; then
  submit_round
  exit $?
fi

# Rounds towards a target error: each round is a whole sharded bake (the same seed, more photons);
# after its merge the report says whether the estimate met the target, else the next round asks
# for the photons the error's 1 / sqrt(photons) fall needs (x 1.2, at least twice as many).
wait=1
for round in $(seq 1 "$max_rounds"); do
  echo "round $round${photons:+: $photons photons}"
  submit_round || exit $?
  read -r met estimate direct used < <(python3 -c 'import json, sys
r = json.load(open(sys.argv[1]))
print(int(r["target"]["met"]), r["stats"]["error_estimate"], r["stats"]["error_direct"], r["settings"]["photon_count"])' \
    "$out/report.json")
  echo "round $round: error estimate $estimate (direct part $direct) with $used photons, target $target"
  [ "$met" = 1 ] && { echo "target met"; exit 0; }
  if python3 -c 'import sys; sys.exit(0 if float(sys.argv[1]) >= float(sys.argv[2]) else 1)' "$direct" "$target"; then
    echo "slurm_bake: the direct pass alone is above the target: more photons cannot reach it" >&2
    exit 3
  fi
  photons=$(python3 -c 'import math, sys
e, t, p = float(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
print(max(2 * p, int(math.ceil(p * 1.2 * (e / t) ** 2 / 4096)) * 4096))' "$estimate" "$target" "$used")
done
echo "slurm_bake: target $target not met after $max_rounds rounds (see $out/report.json)" >&2
exit 3
