"""Thin one side of a cloud: keep every point with x at or over the median and a share SHARE of the
others (a seeded random draw), as a scan whose far side was sampled more sparsely (farther from the
scanner, or seen by fewer views)

Usage: python3 bench/models/sparse_side.py CLOUD.xyz SHARE OUT.xyz [--strays SHARE] [--without-normals]

CLOUD.xyz is `x y z nx ny nz` per line (as sample_cloud.py writes it). SHARE (0 to 1) is the part
of the x < median side kept, drawn with a fixed seed. --strays SHARE adds that share of the kept
count as strays, uniform in the box grown by a tenth of its diagonal on every side, with random
normals (the peers bench's outlier model). With --without-normals only `x y z` is written.
"""
import math
import random
import sys

from oriented_cloud import check_output, points

args = sys.argv[1:]
without_normals = "--without-normals" in args
if without_normals:
    args.remove("--without-normals")
strays = 0.0
if "--strays" in args:
    at = args.index("--strays")
    if at + 1 >= len(args):
        sys.exit(__doc__)
    try:
        strays = float(args[at + 1])
    except ValueError:
        sys.exit(f"sparse_side.py: --strays {args[at + 1]!r} is not a number")
    del args[at : at + 2]
if len(args) != 3:
    sys.exit(__doc__)
src, share_text, out = args
try:
    share = float(share_text)
except ValueError:
    sys.exit(f"sparse_side.py: SHARE {share_text!r} is not a number")
if not (0.0 < share <= 1.0) or not (0.0 <= strays <= 1.0):
    sys.exit("sparse_side.py: SHARE must be over 0 and at most 1, --strays 0 to 1")
check_output("sparse_side.py", out, src)

rows = [values for _, values in points(src)]
if not rows:
    sys.exit(f"{src}: no points")
xs = sorted(r[0] for r in rows)
median = xs[len(xs) // 2]
draw = random.Random(7)
kept = [r for r in rows if r[0] >= median or draw.random() < share]
lo = [min(r[a] for r in kept) for a in range(3)]
hi = [max(r[a] for r in kept) for a in range(3)]
grow = 0.1 * math.dist(lo, hi)
for _ in range(round(strays * len(kept))):
    p = [draw.uniform(lo[a] - grow, hi[a] + grow) for a in range(3)]
    n = [draw.gauss(0.0, 1.0) for _ in range(3)]
    length = math.sqrt(sum(c * c for c in n)) or 1.0
    kept.append(p + [c / length for c in n])
with open(out, "w") as f:
    for r in kept:
        f.write(" ".join(f"{v:.6f}" for v in (r[:3] if without_normals else r)) + "\n")
print(f"{out}: {len(kept)} points, the x < {median:.6f} side at a share of {share}")
