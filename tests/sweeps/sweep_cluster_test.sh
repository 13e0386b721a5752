#!/usr/bin/env bash
# sweep_cluster_test.sh MODE BUILD SOURCE: the README's recipes for a sweep beyond one process,
# run for real on tests/data/cluster_sweep.json (a small sweep: the demo sweep's 40 runs of the
# pyramid and the chain take minutes; this one seconds), checked against one process.
#   reference  one process: `substep sweep SPEC -o BUILD/sweep_cluster/reference.jsonl`
#   parallel   GNU parallel, 4 shards on 2 jobs, then `sweep merge`
#   slurm      a single-node Slurm cluster on loopback (tests/sweeps/slurm_cluster.sh), the spec
#              as a 4-task job array of scripts/sweep-slurm.sh with `sbatch --wait`; task 1 is
#              requeued (`scontrol requeue`) once its shard holds a finished run, and must resume
#              its shard: the runs it had finished stay, byte for byte, and are not run again;
#              then `sweep merge`
# parallel and slurm require the merged records to equal the reference's: the same runs, the same
# settings, metrics, verdicts and state hashes; costs (wall-clock times) aside.
set -euo pipefail
mode=${1:?usage: sweep_cluster_test.sh reference|parallel|slurm BUILD SOURCE}
build=$(cd "${2:?usage: sweep_cluster_test.sh MODE BUILD SOURCE}" && pwd)
source=$(cd "${3:?usage: sweep_cluster_test.sh MODE BUILD SOURCE}" && pwd)
export SUBSTEP=$build/app/substep
spec=$source/tests/data/cluster_sweep.json
root=$build/sweep_cluster
reference=$root/reference.jsonl
work=$root/$mode
start=$SECONDS
fail() { echo "FAIL: $*" >&2; exit 1; }
step() { echo "== [$((SECONDS - start)) s] $*"; }

# The records without what differs between two runs of the same sweep (their costs: wall-clock
# times), as one JSON array sorted by key.
comparable() {
  jq -S -s 'map(del(.cost)) | sort_by(.key)' "$1"
}

# same_as_reference FILE: FILE's records are the reference's.
same_as_reference() {
  [[ -f $reference ]] || fail "no $reference: run the reference first (ctest runs it as this test's fixture)"
  local n_ref n
  n_ref=$(wc -l <"$reference")
  n=$(wc -l <"$1")
  [[ $n == "$n_ref" ]] || fail "$1 has $n records, the one-process sweep $n_ref"
  comparable "$reference" >"$work/reference.cmp.json"
  comparable "$1" >"$work/merged.cmp.json"
  if ! cmp -s "$work/reference.cmp.json" "$work/merged.cmp.json"; then
    diff "$work/reference.cmp.json" "$work/merged.cmp.json" | head -40
    fail "the merged records differ from the one-process sweep's (above: < one process, > merged)"
  fi
  echo "$n records equal to the one-process sweep's (costs aside)"
}

rm -rf "$work"
mkdir -p "$work"
case $mode in
  reference)
    step "one process: substep sweep $spec"
    "$SUBSTEP" sweep "$spec" -o "$work/reference.jsonl.tmp" -q
    mv "$work/reference.jsonl.tmp" "$reference"
    echo "$(wc -l <"$reference") records in $reference"
    ;;

  parallel)
    command -v parallel >/dev/null || fail "no GNU parallel (Debian package parallel)"
    step "parallel --will-cite -j 2 ... --shard {}/4 ::: 1 2 3 4"
    parallel --will-cite --halt now,fail=1 -j 2 "$SUBSTEP" sweep "$spec" --shard {}/4 -o "$work/shard-{}.jsonl" -q ::: 1 2 3 4
    "$SUBSTEP" sweep merge "$work"/shard-*.jsonl -o "$work/all.jsonl"
    same_as_reference "$work/all.jsonl"
    ;;

  slurm)
    # shellcheck source=tests/sweeps/slurm_cluster.sh
    source "$source/tests/sweeps/slurm_cluster.sh"
    submitted=
    stop() {
      [[ -n $submitted ]] && kill "$submitted" 2>/dev/null
      slurm_cluster_stop
    }
    trap stop EXIT
    step "a single-node Slurm cluster on loopback in $work/cluster"
    slurm_cluster_start "$work/cluster"
    sinfo
    step "sbatch --wait --array=1-4 scripts/sweep-slurm.sh"
    mkdir -p "$work/out"
    (cd "$work" && sbatch --wait --array=1-4 --output="$work/task-%a.log" "$source/scripts/sweep-slurm.sh" "$spec" "$work/out" \
      >"$work/sbatch.out" 2>&1) &
    submitted=$!
    job=
    for _ in $(seq 300); do
      job=$(sed -n 's/^Submitted batch job \([0-9]*\)$/\1/p' "$work/sbatch.out")
      [[ -n $job ]] && break
      sleep 0.1
    done
    [[ -n $job ]] || { cat "$work/sbatch.out"; slurm_cluster_logs "$work/cluster"; fail "sbatch submitted no job"; }
    echo "job $job"
    # Requeue task 1 once its shard holds a finished run and it is still running.
    shard=$work/out/shard-1.jsonl
    for _ in $(seq 1200); do
      [[ -s $shard ]] && break
      sleep 0.05
    done
    [[ -s $shard ]] || { slurm_cluster_logs "$work/cluster"; fail "task 1 wrote no run in 60 s"; }
    cp "$shard" "$work/shard-1.before"
    state=$(squeue -h -j "${job}_1" -o %T 2>/dev/null || true)
    [[ $state == RUNNING ]] || fail "task 1 finished before it could be requeued (state \"$state\"): the sweep is too short"
    step "scontrol requeue ${job}_1 after $(wc -l <"$work/shard-1.before") of its runs"
    scontrol requeue "${job}_1"
    wait "$submitted" || { cat "$work/sbatch.out" "$work"/task-*.log; slurm_cluster_logs "$work/cluster"; fail "sbatch --wait: a task failed"; }
    submitted=
    step "every task done"
    restarts=$(scontrol show job "${job}_1" | sed -n 's/.*Restarts=\([0-9]*\).*/\1/p')
    [[ $restarts == 1 ]] || fail "task 1 restarted $restarts times, not once: $(scontrol show job "${job}_1")"
    for i in 1 2 3 4; do
      state=$(scontrol show job "${job}_$i" | sed -n 's/.*JobState=\([A-Z]*\).*/\1/p')
      [[ $state == COMPLETED ]] || fail "task $i ended $state"
    done
    # The runs it had finished before the requeue are still its first lines, unchanged (a run
    # done again would carry another cost), and no run is in the file twice.
    n_before=$(wc -l <"$work/shard-1.before")
    head -n "$n_before" "$shard" | cmp -s - "$work/shard-1.before" ||
      fail "task 1's first $n_before runs changed after the requeue: they were run again"
    dups=$(jq -r .key "$shard" | sort | uniq -d)
    [[ -z $dups ]] || fail "task 1 ran these runs twice: $dups"
    # Its log (of the second start) says what it found done and what it ran: together, the shard.
    cat "$work/task-1.log"
    found=$(sed -n 's/.*; \([0-9]*\) already in .*/\1/p' "$work/task-1.log")
    ran=$(sed -n 's/^wrote .*(\([0-9]*\) new rows).*/\1/p' "$work/task-1.log")
    [[ -n $found && -n $ran ]] || fail "task 1's log does not say what it resumed"
    ((found >= n_before && found + ran == $(wc -l <"$shard"))) ||
      fail "task 1 found $found runs done and ran $ran, for $(wc -l <"$shard") in its shard ($n_before before the requeue)"
    echo "task 1: restarted once; found $found runs done ($n_before seen before the requeue, kept byte for byte), ran the other $ran"
    "$SUBSTEP" sweep merge "$work"/out/shard-*.jsonl -o "$work/all.jsonl"
    same_as_reference "$work/all.jsonl"
    ;;

  *) fail "unknown mode $mode (reference, parallel or slurm)" ;;
esac
step "passed"
