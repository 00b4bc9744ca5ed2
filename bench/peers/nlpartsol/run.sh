#!/bin/bash
# Dyka strip (examples/dyka_2d.toml at CELLS cells along the bar): NL-PartSol,
# and with -o also otmpm, interleaved, one thread each, each timed run under
# flock LOCK. Prints the wall time and particle-steps/s of every run, the
# medians, and (with -o) compares the two codes' particles at t_end.
#
#   run.sh [-n NLPS_BIN] [-o OTMPM_BIN] [-c CELLS] [-r RUNS] [-w WORKDIR]
#          [-s SCENE] [-l LOCK]
#
# NLPS_BIN (NL-PartSol's executable) is required; the defaults of the others
# (also as environment variables): OTMPM_BIN unset (NL-PartSol only),
# CELLS=160, RUNS=1, WORKDIR a new temporary directory,
# SCENE=<repo>/examples/dyka_2d.toml, LOCK unset (no flock).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
NLPS_BIN=${NLPS_BIN:-}
OTMPM_BIN=${OTMPM_BIN:-}
CELLS=${CELLS:-160}
RUNS=${RUNS:-1}
WORKDIR=${WORKDIR:-}
SCENE=${SCENE:-$here/../../../examples/dyka_2d.toml}
LOCK=${LOCK:-}
while getopts "n:o:c:r:w:s:l:" opt; do
  case $opt in
    n) NLPS_BIN=$OPTARG ;; o) OTMPM_BIN=$OPTARG ;; c) CELLS=$OPTARG ;;
    r) RUNS=$OPTARG ;; w) WORKDIR=$OPTARG ;; s) SCENE=$OPTARG ;; l) LOCK=$OPTARG ;;
    *) sed -n 2,13p "$0"; exit 2 ;;
  esac
done
[ -x "$NLPS_BIN" ] || { echo "run.sh: give NL-PartSol's executable with -n (or NLPS_BIN)" >&2; exit 2; }
[ -n "$WORKDIR" ] || WORKDIR=$(mktemp -d)
mkdir -p "$WORKDIR"
export OMP_NUM_THREADS=1

# the scene's step count at cfl 0.1, then dt = t_end / steps for both codes
read -r H STEPS DT < <(python3 -c "
import math
L, c, cfl, t = 0.1333, math.sqrt(200e9 / 7833), 0.1, 1e-4
h = L / $CELLS; n = math.ceil(t / (cfl * h / c) - 1e-9)
print(repr(h), n, repr(t / n))")
NP=$((4 * CELLS))
nl_dir=$WORKDIR/nlps_n$CELLS
python3 "$here/make_dyka.py" --cells "$CELLS" --steps "$STEPS" --out "$nl_dir"

otmpm_args=(--threads 1 --force --out "$WORKDIR/otmpm_n$CELLS.h5"
  --set "grid.cells=[$((CELLS + 2)),1]"
  --set "grid.lower=[$(python3 -c "print(repr(-2 * $H))"),0.0]"
  --set "grid.upper=[0.1333,$H]" --set "body.bar.upper=[0.1333,$H]"
  --set "initial_velocity.0.upper=[0.033325,$H]"
  --set "boundary.right_end.upper=[0.1333,$H]" --set "simulation.dt=$DT")

timed() {  # timed LOGFILE CMD...: wall seconds of CMD (under flock LOCK when LOCK is set)
  local log=$1; shift
  local lock=(); [ -z "$LOCK" ] || lock=(flock "$LOCK")
  "${lock[@]}" bash -c 's=$(date +%s.%N); "$@" > "$0" 2>&1; e=$(date +%s.%N);
    python3 -c "print(round($e - $s, 4))"' "$log" "$@"
}

nl_times=(); ot_times=(); ot_loop=()
for i in $(seq 1 "$RUNS"); do
  if [ -n "$OTMPM_BIN" ]; then
    echo "load: $(uptime | sed 's/.*load average/load average/')"
    t=$(timed "$WORKDIR/otmpm_n$CELLS.log" "$OTMPM_BIN" run "$SCENE" "${otmpm_args[@]}")
    summ=$(grep '^ok:' "$WORKDIR/otmpm_n$CELLS.log")
    # the loop alone: the phase times without 'output'
    loop=$(grep '^phases:' "$WORKDIR/otmpm_n$CELLS.log" | python3 -c "
import re, sys
print(sum(float(v) for k, v in re.findall(r'(\w+) ([0-9.eE+-]+) s', sys.stdin.read()) if k != 'output'))")
    ot_times+=("$t"); ot_loop+=("$loop")
    echo "otmpm      run $i: $t s outside, $summ | phases without output $loop s"
  fi
  echo "load: $(uptime | sed 's/.*load average/load average/')"
  rm -rf "$nl_dir/results" && mkdir -p "$nl_dir/results"
  t=$(cd "$nl_dir" && timed "$nl_dir/log.txt" "$NLPS_BIN" -u dyka.nlps)
  grep -q "succesfully" "$nl_dir/log.txt" || { echo "NL-PartSol failed: $nl_dir/log.txt"; exit 1; }
  nl_times+=("$t")
  echo "NL-PartSol run $i: $t s wall, $(python3 -c "print('%.4g s/step, %.3g particle-steps/s' % ($t / $STEPS, $NP * $STEPS / $t))")"
done

python3 - "$NP" "$STEPS" "${nl_times[*]}" "${ot_times[*]:-}" "${ot_loop[*]:-}" <<'EOF'
import statistics as st, sys
np_, steps = int(sys.argv[1]), int(sys.argv[2])
nl = [float(v) for v in sys.argv[3].split()]
ot = [float(v) for v in sys.argv[4].split()]
lo = [float(v) for v in sys.argv[5].split()]
ps = lambda t: np_ * steps / t
m = st.median(nl)
print("NL-PartSol: %d particles, %d steps; wall %s s; median %.4g s = %.4g particle-steps/s"
      % (np_, steps, nl, m, ps(m)))
if ot:
    mo, ml = st.median(ot), st.median(lo)
    print("otmpm: wall %s s; median %.4g s = %.4g particle-steps/s; loop (phases without output) median %.4g s = %.4g particle-steps/s"
          % (ot, mo, ps(mo), ml, ps(ml)))
    print("ratio otmpm / NL-PartSol in particle-steps/s (whole runs): %.1f" % (m / mo))
EOF

[ -z "$OTMPM_BIN" ] && exit 0
# physics: the particles at t_end, matched by their initial position
python3 - "$WORKDIR/otmpm_n$CELLS.h5" "$nl_dir/results/Particles_$((STEPS - 1)).vtk" 1e-4 <<'EOF'
import math, re, subprocess, sys
h5file, vtk = sys.argv[1], sys.argv[2]
def h5(path):
    out = subprocess.run(["h5dump", "-y", "-w", "0", "-m", "%.17g", "-d", path, h5file],
                         capture_output=True, text=True, check=True).stdout
    body = out[out.index("DATA {") + 6:]
    return [float(v) for v in re.findall(r"[-+0-9.eE]+", body[:body.index("}")])]
frames = subprocess.run(["h5ls", h5file + "/frames"], capture_output=True, text=True).stdout.split()
last = [f for f in frames if f.isdigit()][-1]
x0, x1, v, s = (h5("/frames/%s/%s" % (f, k)) for f, k in
                (("000000", "x"), (last, "x"), (last, "v"), (last, "stress")))
n = len(x0) // 2
ot = [((x0[2*p+1] > 0.5 * max(x0[1::2]), x0[2*p]), (x1[2*p] - x0[2*p], v[2*p], s[4*p])) for p in range(n)]
txt = open(vtk).read().split("\n")
def block(tag, width):
    i = next(k for k, l in enumerate(txt) if l.startswith(tag))
    vals = []
    for l in txt[i + 1:]:
        if len(vals) >= n * width: break
        vals += [float(t) for t in l.split()]
    return vals
pts, vel, dis, sig = block("POINTS", 3), block("VECTORS VELOCITY", 3), block("VECTORS DISPLACEMENT", 3), block("TENSORS STRESS", 9)
ymax = max(pts[3*p+1] - dis[3*p+1] for p in range(n))
nl = [((pts[3*p+1] - dis[3*p+1] > 0.5 * ymax, pts[3*p] - dis[3*p]), (dis[3*p], vel[3*p], sig[9*p])) for p in range(n)]
ot.sort(); nl.sort()  # (row, X): pair the particles by their initial place
gap = max(abs(a[0][1] - b[0][1]) for a, b in zip(ot, nl))
assert all(a[0][0] == b[0][0] for a, b in zip(ot, nl)) and gap < 1e-7, "particles differ"
L = 0.1333
keys = range(n)
ot, nl, X = [a[1] for a in ot], [b[1] for b in nl], [a[0] for a in ot]
mid = min(keys, key=lambda k: (abs(X[k][1] - L / 2), X[k][0]))
print("initial positions agree to %.1e m; particle nearest the middle (lower row), X = %.7g m:" % (gap, X[mid][1]))
for j, name in enumerate(("u_x [m]", "v_x [m/s]", "sigma_xx [Pa]")):
    a, b = ot[mid][j], nl[mid][j]
    print("  %-14s otmpm %+.9e  NL-PartSol %+.9e  rel. diff %.2e" % (name, a, b, abs(a - b) / max(abs(a), 1e-300)))
# the exact 1D solution (characteristics R+- = v -+ sigma / Z, free at 0, fixed at L)
E, rho, t = 200e9, 7833.0, float(sys.argv[3]); c = math.sqrt(E / rho); Z = rho * c
v0 = lambda x: -5.0 if x < L / 4 else 0.0
def Rp(x, t):
    return v0(x - c * t) if x - c * t >= 0 else Rm(0.0, t - x / c)
def Rm(x, t):
    return v0(x + c * t) if x + c * t <= L else -Rp(L, t - (L - x) / c)
ex = [((Rp(x[1], t) + Rm(x[1], t)) / 2, Z * (Rm(x[1], t) - Rp(x[1], t)) / 2) for x in X]
for j, name in ((1, "v_x"), (2, "sigma_xx")):
    e_ot = math.sqrt(sum((ot[k][j] - ex[k][j - 1]) ** 2 for k in keys) / n)
    e_nl = math.sqrt(sum((nl[k][j] - ex[k][j - 1]) ** 2 for k in keys) / n)
    print("rms error against the exact solution at t = %g s, %-8s: otmpm %.4g, NL-PartSol %.4g" % (t, name, e_ot, e_nl))
for j, name in enumerate(("u_x", "v_x", "sigma_xx")):
    d = [ot[k][j] - nl[k][j] for k in keys]
    ref = max(abs(ot[k][j]) for k in keys)
    print("all %d particles, %-8s: max |diff| / max |otmpm| = %.2e, rms diff / max |otmpm| = %.2e"
          % (n, name, max(map(abs, d)) / ref, math.sqrt(sum(x * x for x in d) / n) / ref))
EOF
