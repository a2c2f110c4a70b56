#!/usr/bin/env python3
# Used by docs/online.md: `python3 scripts/cusum_arl.py` prints the ARL of the CUSUM for (nu, h) and variance ratios 1, 2, 4, 10.
# Average run length of Page's CUSUM g = max(0, g + z - nu), alarm g > h, z ~ chi2_1 * r (r: variance ratio),
# by the Markov-chain approximation of Brook & Evans (1972), m states.
import math, sys
def F(x, r):  # P(r*chi2_1 <= x)
    return 0.0 if x <= 0 else math.erf(math.sqrt(x / r / 2.0))
def arl(nu, h, r=1.0, m=300):
    w = h / m
    s = [j * w for j in range(m)]
    A = [[0.0] * m for _ in range(m)]
    for i in range(m):
        for j in range(m):
            up = F(nu - s[i] + (j + 0.5) * w, r)
            lo = F(nu - s[i] + (j - 0.5) * w, r) if j > 0 else 0.0
            A[i][j] = (1.0 if i == j else 0.0) - (up - lo)
    b = [1.0] * m
    for c in range(m):  # Gaussian elimination with partial pivoting
        p = max(range(c, m), key=lambda q: abs(A[q][c]))
        A[c], A[p] = A[p], A[c]; b[c], b[p] = b[p], b[c]
        for q in range(c + 1, m):
            f = A[q][c] / A[c][c]
            if f:
                for k in range(c, m): A[q][k] -= f * A[c][k]
                b[q] -= f * b[c]
    x = [0.0] * m
    for c in range(m - 1, -1, -1):
        x[c] = (b[c] - sum(A[c][k] * x[k] for k in range(c + 1, m))) / A[c][c]
    return x[0]
for nu, h in [(2, 6), (3, 30), (3, 45), (3, 60)]:
    print(nu, h, ["%.3g" % arl(nu, h, r) for r in (1, 2, 4, 10)])
