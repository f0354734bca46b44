#!/usr/bin/env python3
# Adversarial XYZ for pass 3 identity checks (EPSG:32632): a crescent (annulus r 400-600 m over
# 252 deg, 0.5 pt/m^2), 5 Gaussian clusters (sigma 15 m, 5,000 points each) and a dense arc
# (0.05 m spacing, radius 2 km, 600 m long) across the hole and the opening.
import math, random, sys
random.seed(42)
cx, cy = 500000.0, 5500000.0
def h(x, y): return 300.0 + 40.0*math.sin(x/37.0) + 25.0*math.cos(y/53.0)
out = []
area = math.radians(252)/2*(600**2-400**2)
n = int(area*0.5)
for _ in range(n):
    r = math.sqrt(400**2 + random.random()*(600**2-400**2))
    a = math.radians(252)*random.random()
    x, y = cx + r*math.cos(a), cy + r*math.sin(a)
    out.append((x, y))
for k in range(5):
    a = math.radians(20 + 50*k); mx, my = cx + 500*math.cos(a), cy + 500*math.sin(a)
    for _ in range(5000):
        out.append((mx + random.gauss(0, 15), my + random.gauss(0, 15)))
R = 2000.0; L = 600.0; m = int(L/0.05)
acx, acy = cx + 150.0, cy - R - 350.0
for i in range(m):
    t = (-L/2 + (i+0.5)*L/m)/R
    out.append((acx + R*math.sin(t), acy + R*math.cos(t)))
with open(sys.argv[1] if len(sys.argv) > 1 else "adversarial.xyz", "w") as f:
    for x, y in out: f.write("%.3f %.3f %.3f\n" % (x, y, h(x, y)))
print(len(out))
