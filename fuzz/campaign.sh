#!/usr/bin/env bash
# A fuzzing campaign as README.md ("Fuzzing") reports them: WORKERS processes
# of one target's `--sanitizer none -O` build share one corpus, started from
# fuzz/corpus/TARGET, each stopping after RUNS executions; the count is the
# sum of their stat::number_of_executed_units. Workers run at nice 10, so a
# build or CI on the same cores goes first.
#
#   fuzz/campaign.sh TARGET WORKERS RUNS DIR [libFuzzer flags...]
#   fuzz/campaign.sh api_sequence 2 5000000 /work/fuzzrun/run -max_len=256 -entropic=0
#
# A campaign is DIR: its binary (TARGET.COMMIT, built once, from a tree
# whose code is committed), its corpus and one log per worker and run.
# Running the script again on DIR continues the campaign with the same
# binary, so a campaign may span sessions; the campaign's count is the sum
# over all its logs. Stopping early: SIGINT to the workers (Ctrl-C, or
# `pkill -INT -f DIR/TARGET.`). Each logs its count, and the script still
# reports the totals.
#
# Comparison tracing helps only where raw input bytes meet magic values
# (decode_block, open_and_query). The other targets' input only chooses
# operations, or fields and values that the forger seals: there it halves
# the rate and adds no reach (forge_lod, 180 s each from fuzz/corpus:
# 287,066 runs to cov 4681 ft 15527 with it; 514,338 to cov 4740 ft 16742
# without, and cov 4677 ft 15404 at its 289,950th). Those are built with
# --no-trace-compares.
set -euo pipefail
[ $# -ge 4 ] || { echo "usage: $0 TARGET WORKERS RUNS DIR [libFuzzer flags...]" >&2; exit 2; }
target=$1 workers=$2 runs=$3 dir=$4
shift 4
cd "$(dirname "$0")"
mkdir -p "$dir/corpus" "$dir/artifacts"
shopt -s nullglob
kept=("$dir/$target".*)
case ${#kept[@]} in
  0)
    # The binary is named by its commit: the code it is built from must be that commit's.
    git diff --quiet HEAD -- :/src :/Cargo.toml :/Cargo.lock :/README.md fuzz_targets alloc_limit.rs Cargo.toml Cargo.lock ||
      { echo "$0: commit the code first: the binary is named by its commit" >&2; exit 2; }
    trace=()
    case $target in decode_block | open_and_query) ;; *) trace=(--no-trace-compares) ;; esac
    cargo fuzz build --sanitizer none -O "${trace[@]}" "$target"
    binary="$dir/$target.$(git rev-parse --short HEAD)"
    cp "target/x86_64-unknown-linux-gnu/release/$target" "$binary"
    ;;
  1) binary=${kept[0]} ;;
  *) echo "$0: $dir holds more than one $target binary" >&2; exit 2 ;;
esac
cp -rn "corpus/$target/." "$dir/corpus/"
run=1
while [ -e "$dir/run$run.w1.log" ]; do run=$((run + 1)); done
# The script outlives a SIGINT meant for the workers, to count what they ran.
trap '' INT
for w in $(seq 1 "$workers"); do
  nice -n 10 "$binary" "$dir/corpus" -runs="$runs" -timeout=60 -print_final_stats=1 \
    -artifact_prefix="$dir/artifacts/" "$@" > "$dir/run$run.w$w.log" 2>&1 &
done
wait
executed() { grep -h '^stat::number_of_executed_units' "$@" | awk '{s += $2} END {print s + 0}'; }
logs=("$dir"/*.log)
echo "$target: $(executed "$dir"/run$run.w*.log) executions in run $run over $workers workers;" \
  "$(executed "${logs[@]}") in the campaign's ${#logs[@]} logs ($binary); artifacts: $(ls "$dir/artifacts" | wc -l)"
