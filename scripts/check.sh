#!/usr/bin/env bash
# Everything CI checks, in the order a developer wants the failures: format, lints, layering,
# tests (the README's test command). One debug build serves clippy and the tests.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== rustfmt"
cargo fmt --all -- --check

echo "== clippy"
cargo clippy --workspace --all-targets -- -D warnings

echo "== layering: the volume core depends on no GPU, UI or windowing crate"
if cargo tree -p strata-volume -e normal | grep -E '(wgpu|egui|eframe|winit) v'; then
  echo "strata-volume must not depend on the crates above" >&2
  exit 1
fi

echo "== tests"
cargo test --workspace
