#!/usr/bin/env bash
# Fails where a SIMD intrinsic is compiled as a function of its own in the hemi binary: inside a
# kernel every intrinsic must be inlined. One left out of line means code that calls it was
# compiled without the kernel's instruction set (a closure, or a generic that stayed out of
# line: docs/design.md, "Written once, generic over lane width"), and each of its vector
# operations became a call. Only the CPU check's `_xgetbv` runs outside a kernel.
#
#   scripts/check-inlined-intrinsics.sh [BINARY]     (default target/release/hemi)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
binary="${1:-$root/target/release/hemi}"
[ -x "$binary" ] || { echo "check-inlined-intrinsics: $binary is not an executable (build with cargo build --release)" >&2; exit 1; }
command -v nm >/dev/null || { echo "check-inlined-intrinsics: needs nm (binutils)" >&2; exit 1; }
left="$(nm -C "$binary" | grep -E 'core::core_arch::x86(_64)?::' | grep -v -E '::_xgetbv$' || true)"
if [ -n "$left" ]; then
    echo "check-inlined-intrinsics: intrinsics compiled as calls in $binary:" >&2
    echo "$left" >&2
    exit 1
fi
echo "check-inlined-intrinsics: every intrinsic in $(basename "$binary") is inlined"
