"""Append strays to a cloud: FRACTION of its point count, spread evenly over its box widened by
a tenth of its size (a twentieth on each side), each with a normal pointing anywhere.

Usage: python3 bench/models/add_strays.py IN.xyz FRACTION OUT.xyz SEED

IN.xyz holds `x y z nx ny nz` lines (as sample_cloud.py writes them); OUT.xyz must differ from it.
"""
import math, os, random, sys
src, frac, out, seed = sys.argv[1], float(sys.argv[2]), sys.argv[3], int(sys.argv[4])
if os.path.abspath(src) == os.path.abspath(out):
    sys.exit("add_strays.py: the output would replace the input")
lines = [l for l in open(src) if l.strip()]
pts = [list(map(float, l.split()[:3])) for l in lines]
lo = [min(p[i] for p in pts) for i in range(3)]
hi = [max(p[i] for p in pts) for i in range(3)]
rng = random.Random(seed)
with open(out, 'w') as f:
    f.writelines(lines)
    for _ in range(int(len(pts) * frac)):
        q = [lo[i] - (hi[i] - lo[i]) * 0.05 + rng.random() * (hi[i] - lo[i]) * 1.1 for i in range(3)]
        v = [rng.gauss(0, 1) for _ in range(3)]
        n = math.sqrt(sum(x * x for x in v))
        f.write("%.6f %.6f %.6f %.5f %.5f %.5f\n" % (*q, *(x / n for x in v)))
