#!/usr/bin/env bash
# A fuzzing campaign as README.md ("Fuzzing") reports them: WORKERS processes
# of one target's `--sanitizer none -O` build share one corpus, started from
# fuzz/corpus/TARGET, each stopping after RUNS executions; the total is the
# sum of their stat::number_of_executed_units. Workers run at nice 10, so a
# build or CI on the same cores goes first.
#
#   fuzz/campaign.sh TARGET WORKERS RUNS DIR [libFuzzer flags...]
#   fuzz/campaign.sh api_sequence 2 5000000 /work/fuzzrun/run -max_len=256 -entropic=0
#
# api_sequence's input only chooses operations, so comparison tracing adds
# cost and no reach: that target is built with --no-trace-compares.
set -euo pipefail
[ $# -ge 4 ] || { echo "usage: $0 TARGET WORKERS RUNS DIR [libFuzzer flags...]" >&2; exit 2; }
target=$1 workers=$2 runs=$3 dir=$4
shift 4
cd "$(dirname "$0")"
trace=()
[ "$target" = api_sequence ] && trace=(--no-trace-compares)
cargo fuzz build --sanitizer none -O "${trace[@]}" "$target"
mkdir -p "$dir/corpus" "$dir/artifacts"
cp -rn "corpus/$target/." "$dir/corpus/"
binary="$dir/$target.$(git rev-parse --short HEAD)"
cp "target/x86_64-unknown-linux-gnu/release/$target" "$binary"
for w in $(seq 1 "$workers"); do
  nice -n 10 "$binary" "$dir/corpus" -runs="$runs" -timeout=60 -print_final_stats=1 \
    -artifact_prefix="$dir/artifacts/" "$@" > "$dir/w$w.log" 2>&1 &
done
wait
total=$(grep -h '^stat::number_of_executed_units' "$dir"/w*.log | awk '{s += $2} END {print s}')
echo "$target: $total executions over $workers workers ($binary); artifacts: $(ls "$dir/artifacts" | wc -l)"
