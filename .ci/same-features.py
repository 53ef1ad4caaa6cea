#!/usr/bin/env python3
"""The README's two first commands share one build of the dependencies only if
`cargo run --release -- demo` (the mktree-cli package) and `cargo test --release`
(the workspace's default members with their dev-dependencies; the Python package,
python/, is a member built by maturin only) ask for the same features of every
crate they share; cargo builds a crate again for any other set. This compares the two
feature resolutions (`cargo tree -e features`) and names each crate that differs."""
import subprocess, sys

def features(*selection):
    out = subprocess.run(
        ["cargo", "tree", *selection, "-f", "{p} [{f}]", "--prefix", "none"],
        check=True, capture_output=True, text=True).stdout
    crates = {}
    for line in out.splitlines():
        head, _, feats = line.replace(" (*)", "").partition(" [")
        if head:
            crates[" ".join(head.split(" ")[:2])] = feats.rstrip("]")
    return crates

run = features("-p", "mktree-cli", "-e", "normal,build")
# No package named: the default members, what `cargo test --release` builds.
test = features("-e", "normal,build,dev")
differ = [f"{c}: demo [{run[c]}], tests [{test[c]}]" for c in sorted(run) if c in test and run[c] != test[c]]
for d in differ:
    print(d)
if differ:
    print(f"{len(differ)} crates would be built twice; ask for the tests' features in cli/Cargo.toml")
    sys.exit(1)
print(f"the demo's {len(run)} crates build once for both commands")
