"""1000 tool strokes over the default block (top face and the four sides), brushes from 1/512
to 1/32 of the clay's size, as a dynaclay script on stdout."""
import random, sys
random.seed(int(sys.argv[1]) if len(sys.argv) > 1 else 1)
SIZE = 2.3; LO = 0.575; HI = 1.725
print("version = 1")
for n in range(1000):
    r = 0.5 * SIZE / random.choice([256, 128, 64, 32])
    face = random.choice(["top", "x+", "x-", "z+", "z-"])
    u, v = random.uniform(LO + 0.05, HI - 0.05), random.uniform(LO + 0.05, HI - 0.05)
    pts = []
    for k in range(5):
        du = 0.01 * k
        if face == "top": p = (u + du, HI, v)
        elif face == "x+": p = (HI, u + du, v)
        elif face == "x-": p = (LO, u + du, v)
        elif face == "z+": p = (u + du, v, HI)
        else: p = (u + du, v, LO)
        pts.append("[%.4f, %.4f, %.4f]" % p)
    action = '{ kind = "remove" }' if n % 2 == 0 else '{ kind = "add", deposit_rate_per_s = 4.0 }'
    print('[[step]]\ndo = "tool"\nshape = { kind = "sphere", radius_fu = %.5f }\naction = %s\npositions = [%s]\nduration_s = 0.2\nfalloff_fu = %.5f\n' % (r, action, ", ".join(pts), 0.25 * r))
