#!/usr/bin/env bash
# Runs hemi, native Embree 3 (C++, ../shared/peers/native: the best of its stream and packet
# modes, with its default fast triangle test and with RTC_SCENE_FLAG_ROBUST, its watertight one,
# the guarantee hemi's triangles give), Embree 4 (embreex) and Mitsuba 3 (llvm_ad_rgb) on the same
# peer scenes, one after the other in one run, and prints AO-ray throughput, render time and the
# ratios.
#
#   scripts/compare-peers.sh [--spp N] [--threads N] [--rounds N] [--split] [SCENE ...]   (default: all five)
#
# --rounds N runs every scene N times, round by round (so a slow spell of a shared machine hits
# all three renderers alike), prints each run, then per scene the median ratios and their range.
# --split also renders, in each round, a copy of each scene whose AO rays are 1e-7 long, with
# hemi and Mitsuba: what their AO kernels spend on such rays (sampling, set-up, sums, and the
# queries' walk down to the nodes around each ray's origin) against what the real rays add.
#
# With HEMI_NO_AVX512=1 hemi runs its AVX2 kernels and native Embree an AVX2 build of its bench
# (scripts/native-embree.sh), so that column compares eight lanes with eight; Embree 4 and
# Mitsuba 3 still run on the CPU's own instruction set.
#
# SCENE is a name from ../shared/peers/scenes (cornell, sphere_plane, many_spheres, dragon,
# sponza). The peers run from a writable copy in $HEMI_PEERS_DIR (default /tmp/hemi-peers) with
# their own venv, set up on first use as ../shared/peers/README.md describes (Mitsuba's llvm
# variant needs libLLVM 19 from Debian: installed with apt-get when missing and run as root).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
peers_src="$root/../shared/peers"
spp=256
threads=2
rounds=1
split=0
scenes=()
while [ $# -gt 0 ]; do
    case "$1" in
        --spp) spp="$2"; shift 2 ;;
        --threads) threads="$2"; shift 2 ;;
        --rounds) rounds="$2"; shift 2 ;;
        --split) split=1; shift ;;
        -h|--help) sed -n '2,23p' "$0"; exit 0 ;;
        *) scenes+=("$1"); shift ;;
    esac
done
[ ${#scenes[@]} -gt 0 ] || scenes=(sphere_plane cornell many_spheres dragon sponza)
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "compare-peers: --rounds wants a positive whole number, not '$rounds'" >&2; exit 2; }
[ -d "$peers_src" ] || { echo "compare-peers: $peers_src not found (../shared must sit beside the repo)" >&2; exit 1; }

. "$root/scripts/peers-venv.sh"
. "$root/scripts/native-embree.sh"

(cd "$root" && cargo build --release -q)
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
. "$root/scripts/fresh-copy.sh"
hemi="$(fresh_copy "$root/target/release/hemi" "$out")"
json() { python3 -c "import json,sys; d=json.loads(sys.stdin.read().strip().splitlines()[-1]); print($1)"; }

printf '%-13s %5s | %-49s | %-19s | %-28s | %-28s | %s\n' scene spp "hemi: s, AO Mrays/s (trace, kernel, queries)" "native: AO, robust" "embree: s, AO Mrays/s" "mitsuba: s, AO Mrays/s" "hemi kernel/native, /native robust, hemi/mitsuba (kernel, trace), hemi/embree (trace)"
for _ in $(seq "$rounds"); do
for s in "${scenes[@]}"; do
    "$hemi" render "$peers_src/scenes/$s.json" --spp "$spp" --threads "$threads" --out "$out/$s.png" \
        --stats-json "$out/$s.json" 2>/dev/null
    h_s=$(json "round(d['total']['seconds'],2)" < "$out/$s.json")
    h_ao=$(json "round(d['total']['ao_mrays_per_s'],2)" < "$out/$s.json")
    h_aok=$(json "round(d['total']['ao_kernel_mrays_per_s'],2)" < "$out/$s.json")
    h_aoq=$(json "round(d['total']['ao_query_mrays_per_s'],2)" < "$out/$s.json")
    n_line=$(native_best "$s" "$spp" "$threads" --repeat 3 || true)
    n_ao=$(echo "$n_line" | json "d['ao_mrays_s']" 2>/dev/null || echo nan)
    r_line=$(native_best "$s" "$spp" "$threads" --repeat 3 --robust || true)
    r_ao=$(echo "$r_line" | json "d['ao_mrays_s']" 2>/dev/null || echo nan)
    e_line=$(cd "$work" && .venv/bin/python embree_ao.py "$peers_src/scenes/$s.json" --spp "$spp" --threads "$threads" --out "$out/$s.embree" 2>/dev/null | tail -1 || true)
    if [ -n "$e_line" ] && e_s=$(echo "$e_line" | json "d['render_s']" 2>/dev/null); then
        e_ao=$(echo "$e_line" | json "d['ao_incl_gen_mrays_s']")
    else
        echo "compare-peers: embree failed on $s (run embree_ao.py by hand to see why)" >&2
        e_s=nan; e_ao=nan
    fi
    m_line=$(cd "$work" && .venv/bin/python mitsuba_ao.py "$peers_src/scenes/$s.json" --spp "$spp" --threads "$threads" --repeat 2 --out "$out/$s.mitsuba" 2>/dev/null | tail -1 || true)
    if [ -n "$m_line" ] && echo "$m_line" | json "d['ao_mrays_s']" >/dev/null 2>&1; then
        m_s=$(echo "$m_line" | json "d['all_runs_render_s'][-1] if d.get('all_runs_render_s') else d['render_s']")
        m_ao=$(echo "$m_line" | json "d['ao_mrays_s']")
    else
        echo "compare-peers: mitsuba failed on $s (run mitsuba_ao.py by hand to see why)" >&2
        m_s=nan; m_ao=nan
    fi
    ratio=$(python3 -c "print(f'{$h_aok/$n_ao:.2f}x, {$h_aok/$r_ao:.2f}x, {$h_aok/$m_ao:.2f}x, {$h_ao/$m_ao:.2f}x, {$h_ao/$e_ao:.2f}x')" 2>/dev/null || echo "-")
    printf '%-13s %5s | %10s s %12s %12s %12s | %9s %9s | %10s s %12s       | %10s s %12s       | %s\n' "$s" "$spp" "$h_s" "$h_ao" "$h_aok" "$h_aoq" "$n_ao" "$r_ao" "$e_s" "$e_ao" "$m_s" "$m_ao" "$ratio"
    echo "$s $h_s $h_ao $h_aok $h_aoq $e_s $e_ao $m_s $m_ao $n_ao $r_ao" >> "$out/runs.txt"
    if [ "$split" = 1 ]; then
        # The scene with 1e-7-long AO rays (mesh paths made absolute), then both kernels' seconds on
        # it beside those of the run above.
        python3 - "$peers_src/scenes/$s.json" "$out/$s.stub.json" <<'PY'
import json, os, sys
src, dst = sys.argv[1:]
d = json.load(open(src))
here = os.path.dirname(os.path.abspath(src))
d["mesh"] = [os.path.join(here, m) for m in d["mesh"]] if isinstance(d["mesh"], list) else os.path.join(here, d["mesh"])
d["ao"]["max_distance"] = 1e-7
json.dump(d, open(dst, "w"))
PY
        "$hemi" render "$out/$s.stub.json" --spp "$spp" --threads "$threads" --out "$out/$s.stub.png" \
            --stats-json "$out/$s.stub.hemi.json" 2>/dev/null
        h_full=$(json "d['total']['ao_seconds']" < "$out/$s.json")
        h_stub=$(json "d['total']['ao_seconds']" < "$out/$s.stub.hemi.json")
        m_full=$(echo "$m_line" | json "d['ao_kernel_exec_s']" 2>/dev/null || echo nan)
        m_stub=$(cd "$work" && .venv/bin/python mitsuba_ao.py "$out/$s.stub.json" --spp "$spp" --threads "$threads" \
            --repeat 2 --out "$out/$s.stub.mitsuba" 2>/dev/null | tail -1 | json "d['ao_kernel_exec_s']" 2>/dev/null || echo nan)
        echo "$s $h_full $h_stub $m_full $m_stub" >> "$out/split.txt"
    fi
done
done
if [ "$rounds" -gt 1 ]; then
    echo "Over $rounds runs per scene: median (lowest-highest); 'runs >= 1': runs where hemi's AO kernel reached Mitsuba's."
    python3 - "$out/runs.txt" <<'PY'
import math, statistics, sys
runs = {}
for line in open(sys.argv[1]):
    name, *v = line.split()
    runs.setdefault(name, []).append([float(x) for x in v])
def spread(xs):
    xs = [x for x in xs if math.isfinite(x)]
    return f"{statistics.median(xs):.2f}x ({min(xs):.2f}-{max(xs):.2f})" if xs else "-"
print(f"{'scene':13s} | {'kernel / native':18s} | {'kernel / robust':18s} | {'kernel / mitsuba':18s} | runs >= 1 | {'trace / mitsuba':18s} | {'queries / mitsuba':18s} | "
      f"{'hemi s / mitsuba s':18s} | {'trace / embree':18s}")
for name, rows in runs.items():
    h_s, h_ao, h_aok, h_aoq, e_s, e_ao, m_s, m_ao, n_ao, r_ao = zip(*rows)
    kernel = [k / m for k, m in zip(h_aok, m_ao)]
    print(f"{name:13s} | {spread([k / n for k, n in zip(h_aok, n_ao)]):18s} | {spread([k / r for k, r in zip(h_aok, r_ao)]):18s} | {spread(kernel):18s} | {sum(k >= 1 for k in kernel):2d} of {len(rows):<3d} | "
          f"{spread([t / m for t, m in zip(h_ao, m_ao)]):18s} | {spread([q / m for q, m in zip(h_aoq, m_ao)]):18s} | "
          f"{spread([h / m for h, m in zip(h_s, m_s)]):18s} | {spread([t / e for t, e in zip(h_ao, e_ao)]):18s}")
PY
fi
echo "AO Mrays/s: hemi trace = AO rays / trace-system wall time (camera and shadow rays and shading included);"
echo "hemi kernel = AO rays / the trace time spent in the ambient occluder (its sampling, AO rays and sums:"
echo "the part Mitsuba's number times), from cycle counts of every sixteenth pixel; hemi queries = AO rays / the"
echo "part of that in the AO rays' BVH queries alone (traversal and triangle tests; no sampling, set-up or sums;"
echo "timed in a quarter of those pixels);"
echo "native = native Embree 3's ao_mrays_s (AO rays over its AO phase, generation included), best of --stream, --packet 8 and 16${native_isa:+, its $native_isa build};"
echo "robust = the same with --robust (RTC_SCENE_FLAG_ROBUST: watertight triangle tests and conservative traversal, as hemi's);"
echo "embree = ao_incl_gen_mrays_s (numpy ray generation + occlusion); mitsuba = ao_mrays_s (whole AO kernel, warm run)."
if [ "$split" = 1 ]; then
    echo "AO kernel ms with rays 1e-7 long ('stub': sampling, set-up, sums, the walk to the origin's nodes) and"
    echo "what the scene's real rays add ('rest' = full - stub); medians over the rounds."
    python3 - "$out/split.txt" <<'PY'
import statistics, sys
runs = {}
for line in open(sys.argv[1]):
    name, *v = line.split()
    runs.setdefault(name, []).append([1e3 * float(x) for x in v])
print(f"{'scene':13s} | {'hemi full':>9s} {'stub':>7s} {'rest':>7s} | {'mitsuba full':>12s} {'stub':>7s} {'rest':>7s} | "
      f"{'stub h/m':>8s} {'rest h/m':>8s}")
for name, rows in runs.items():
    hf, hs, mf, ms = (statistics.median(c) for c in zip(*rows))
    print(f"{name:13s} | {hf:9.1f} {hs:7.1f} {hf - hs:7.1f} | {mf:12.1f} {ms:7.1f} {mf - ms:7.1f} | "
          f"{hs / ms:7.2f}x {(hf - hs) / (mf - ms):7.2f}x")
PY
fi
