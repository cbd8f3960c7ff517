# Sourced by compare-peers.sh and compare-kernels.sh with $peers_src set: makes the peers' venv
# in $work (HEMI_PEERS_DIR, default /tmp/hemi-peers) on first use, as ../shared/peers/README.md
# describes, and points Dr.Jit at libLLVM 19 (installed with apt-get when missing and run as root).
work="${HEMI_PEERS_DIR:-/tmp/hemi-peers}"
if [ ! -x "$work/.venv/bin/python" ]; then
    echo "$(basename "$0" .sh): setting up the peers in $work (pip install, a few minutes)" >&2
    rm -rf "$work" && cp -r "$peers_src" "$work" && chmod -R u+w "$work"
    python3 -m venv "$work/.venv"
    "$work/.venv/bin/pip" install -q -r "$work/requirements.txt"
fi
llvm=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
if [ ! -e "$llvm" ] && [ "$(id -u)" = 0 ]; then
    apt-get install -y -q libllvm19 >/dev/null 2>&1 || { apt-get update -q >/dev/null && apt-get install -y -q libllvm19 >/dev/null; }
fi
export DRJIT_LIBLLVM_PATH="$llvm"
