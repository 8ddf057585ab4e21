"""Interior consistency of the force operators: nodal residual for
 (a) a uniform pressure block (p = p0, no gravity): f_i = sum V p S_i  (should be 0 at interior nodes)
 (b) a linear hydrostatic column p = rho g (H - y) with gravity: f_i - g m_i (should be 0)
for interior nodes (support fully inside the body), regular lattice at all 8 offsets and a
jittered lattice (particle domains = intervals between neighbour midpoints, so they tile the body).
Residuals relative to rho g h (for (b)) and p0 / h * h (for (a))."""
import numpy as np
from schemes import wbar, sbar, m1bar, grid_ls_grad, pt
from model import rho, g, H, h, NL

rng = np.random.default_rng(0)
for jit in [0.0, 0.2]:
    worst = {}
    for ppa in (2, 3):
        for j in range(8):
            dx = h / ppa
            Y = (np.arange(NL * ppa) + 0.5) * dx + jit * dx * (rng.random(NL * ppa) - 0.5)
            edges = np.concatenate([[0], 0.5 * (Y[1:] + Y[:-1]), [H]])
            l = np.diff(edges); xc = 0.5 * (edges[1:] + edges[:-1])   # domain centres / lengths
            V = l
            yi = -j * h / 8 + np.arange(-3, NL + 4) * h
            inner = (yi - 1.75 * h > 0) & (yi + 1.75 * h < H)
            W, Bw, G, _ = pt(Y, yi)
            Wb, Sb, M1 = wbar(xc, yi, l), sbar(xc, yi, l), m1bar(xc, yi, l)
            m = rho * V
            p_lin = rho * g * (H - Y); p_lin_c = rho * g * (H - xc)
            for name, fa, fb in [
                ('apic', Bw.T @ V, Bw.T @ (V * p_lin) - g * (W.T @ m)),
                ('mls', G.T @ V, G.T @ (V * p_lin) - g * (W.T @ m)),
                ('domlin+gridLS', Sb.T @ V + M1.T @ (V * grid_ls_grad(xc, yi, l, np.ones_like(xc), W)),
                 Sb.T @ (V * p_lin_c) + M1.T @ (V * grid_ls_grad(xc, yi, l, p_lin_c, wbar(xc, yi, l))) - g * (Wb.T @ m)),
            ]:
                ra = np.abs(fa[inner]).max() * h        # uniform p0 = 1: relative to p0
                rb = np.abs(fb[inner]).max() / (rho * g * h)
                wa, wb = worst.get(name, (0, 0))
                worst[name] = (max(wa, ra), max(wb, rb))
    print('jitter %.1f dx:' % jit, '; '.join('%s: uniform %.1e, linear %.1e' % (k, a, b) for k, (a, b) in worst.items()))
