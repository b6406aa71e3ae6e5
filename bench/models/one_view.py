"""Keep one view of a cloud: the points a scanner looking along -VIEW would see on a convex part

Usage: python3 bench/models/one_view.py CLOUD.xyz front|side|top OUT.xyz [--without-normals]

CLOUD.xyz is `x y z nx ny nz` per line (as sample_cloud.py writes it). A point is kept when its
normal faces the view by more than 0.2 (front: +z, side: +x, top: +y), the rest of the object
being out of sight; nothing is occluded, so a hollow facing the view is seen whole. With
--without-normals only `x y z` is written, as a depth camera's cloud comes.
"""
import sys

from oriented_cloud import check_output, points

VIEWS = {"front": (0.0, 0.0, 1.0), "side": (1.0, 0.0, 0.0), "top": (0.0, 1.0, 0.0)}
FACING = 0.2

if len(sys.argv) not in (4, 5) or sys.argv[2] not in VIEWS or (
    len(sys.argv) == 5 and sys.argv[4] != "--without-normals"
):
    sys.exit(__doc__)
src, view, out = sys.argv[1], VIEWS[sys.argv[2]], sys.argv[3]
without_normals = len(sys.argv) == 5
check_output("one_view.py", out, src)
kept = 0
with open(out, "w") as f:
    for fields, values in points(src):
        if sum(a * b for a, b in zip(values[3:], view)) > FACING:
            f.write(" ".join(fields[:3] if without_normals else fields) + "\n")
            kept += 1
print(f"{out}: {kept} points facing {sys.argv[2]}")
