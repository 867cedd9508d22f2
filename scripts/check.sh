#!/usr/bin/env bash
# Everything CI checks, in the order a developer wants the failures: format, lints, layering,
# tests (the README's test command). One debug build serves clippy and the tests.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== rustfmt"
cargo fmt --all -- --check

echo "== clippy"
cargo clippy --workspace --all-targets -- -D warnings

echo "== layering: the volume core, the editor core, the terrain crate and the network crates depend on no GPU, UI or windowing crate"
for core in strata-volume strata-editor strata-terrain strata-net strata-server; do
  if cargo tree -p "$core" -e normal | grep -E '(wgpu|egui|eframe|winit) v'; then
    echo "$core must not depend on the crates above" >&2
    exit 1
  fi
done

echo "== layering: the CLI links no GUI, the renderer no volume or mesh crate"
if cargo tree -p strata -e normal | grep -E '(eframe|egui|winit|rfd) v'; then
  echo "strata (the CLI) must not depend on the crates above" >&2
  exit 1
fi
if cargo tree -p strata-render -e normal | grep -E 'strata-(volume|mesh) v'; then
  echo "strata-render must not depend on the crates above (it is fed plain meshes)" >&2
  exit 1
fi

echo "== tests"
cargo test --workspace
