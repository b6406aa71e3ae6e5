"""A 512³-equivalent sculpt: tool strokes whose brushes are fine enough that automatic detail
refines under them to a knot spacing of 1/512 of the clay's size or finer (level 5 on the
default block: 0.1 / 32 = 0.003125, 1/736 of its 2.3), over a limited part of the clay (a
square of 0.4 on the middle of the top face), as a dynaclay script on stdout.

Run: python3 bench/fine_region.py [strokes] [seed] > s.toml;
/usr/bin/time -v target/release/dynaclay run --lockstep --no-rt --script s.toml --out out/
"""
import random, sys

strokes = int(sys.argv[1]) if len(sys.argv) > 1 else 300
random.seed(int(sys.argv[2]) if len(sys.argv) > 2 else 1)
SIZE = 2.3; MID = 1.15; TOP = 1.725; HALF = 0.2
# Ball radii whose width (twice the radius) needs level 5 on the base's spacing of 0.1: the
# rule is level = ceil(log2(3 * 0.1 / width)), 5 for widths in [0.3/32, 0.3/16).
RADII = [0.0050, 0.0065, 0.0080, 0.0090]
print("version = 1")
for n in range(strokes):
    r = random.choice(RADII)
    u, v = random.uniform(MID - HALF, MID + HALF), random.uniform(MID - HALF, MID + HALF)
    pts = ", ".join("[%.4f, %.4f, %.4f]" % (u + 0.004 * k, TOP, v) for k in range(5))
    action = '{ kind = "remove" }' if n % 2 == 0 else '{ kind = "add", deposit_rate_per_s = 4.0 }'
    print('[[step]]\ndo = "tool"\nshape = { kind = "sphere", radius_fu = %.5f }\naction = %s\n'
          'positions = [%s]\nduration_s = 0.2\nfalloff_fu = %.5f\n' % (r, action, pts, 0.25 * r))
