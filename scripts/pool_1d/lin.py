"""Linear static model about the exact deformed state (fast, for screening corrections).

Particles at x_p = Y_p + U(Y_p), U = exact compression displacement; exact pressure p*_p.
Residual of the discrete node balance for p*:  r_i = sum_p V_p p*_p S_ip - g sum_p m w_ip
(+ floor reaction lam c_i, c = ghost weights, constraint sum_i w_i(0) du_i = 0).
Correction: K_t = S^T diag(V dp/de) B;  K_t du = -r;  dp_p = dp/de (B du)_p.
Result p = p* + dp.  (Path effects of the dynamic run are not modelled.)
Operators B (strain) and S (force) are given per scheme by ops(x, yi, dx) -> (W, B, S).
Engine offset convention j: node rows at -j h/8 + i h.
"""
import numpy as np
from model import rho, K, gam, g, H, h, NL, wq, dwq, press, layer_err

def wint(r):
    """Antiderivative of the quadratic B-spline in r (units of h), W(-inf)=0."""
    r = np.asarray(r, float)
    out = np.zeros_like(r)
    a = np.clip(r, -1.5, 1.5)
    # piecewise: [-1.5,-0.5]: (1.5+r)^3/6 ; [-0.5,0.5]: 1/6 + (0.75 r - r^3/3) - (0.75*(-0.5) + 1/24)
    m1 = a <= -0.5
    m2 = (a > -0.5) & (a <= 0.5)
    m3 = a > 0.5
    out[m1] = (1.5 + a[m1]) ** 3 / 6
    out[m2] = 1 / 6 + 0.75 * (a[m2] + 0.5) - (a[m2] ** 3 + 0.125) / 3
    out[m3] = 1 - (1.5 - a[m3]) ** 3 / 6
    return out


def ops_apic(x, yi, dx):
    r = (x[:, None] - yi[None, :]) / h
    W = wq(r); Bw = dwq(r) / h
    return W, Bw, Bw


def ops_mls(x, yi, dx):
    r = (x[:, None] - yi[None, :]) / h
    W = wq(r); G = W * (yi[None, :] - x[:, None]) * 4 / h ** 2
    return W, G, G


def setup(ppa, j, shift=True):
    dx = h / ppa
    Y = (np.arange(NL * ppa) + 0.5) * dx
    pstar = rho * g * (H - Y)
    # J from p*: J = (1 + gam p/K)^(-1/gam); U(Y) = int_0^Y (J-1)
    Jf = lambda y: (1 + gam * rho * g * (H - y) / K) ** (-1 / gam)
    yy = np.linspace(0, H, 4001)
    Uc = np.concatenate([[0], np.cumsum(0.5 * (Jf(yy[1:]) + Jf(yy[:-1])) - 1) * (yy[1] - yy[0])])
    U = np.interp(Y, yy, Uc) if shift else 0 * Y
    x = Y + U
    yi = -j * h / 8 + np.arange(-3, NL + 4) * h
    return Y, x, yi, dx, pstar, Jf(Y)


def ghostw(yi, dx, ops):
    yq = -(np.arange(40) + 0.5) * dx
    W, B, S = ops(yq, yi, dx)
    c = S.sum(0)
    return c / c.sum()


def solve(ppa, j, ops=ops_apic, shift=True, Sforce=None, retall=False):
    Y, x, yi, dx, ps, J = setup(ppa, j, shift)
    W, B, S = ops(x, yi, dx)
    act = W.sum(0) > 0
    W, B, S, yi = W[:, act], B[:, act], S[:, act], yi[act]
    V = dx * J
    m = rho * dx
    kp = -K * J ** (-gam)                      # dp/de
    r = S.T @ (V * ps) - g * m * W.sum(0)
    c = ghostw(yi, dx, ops)
    wfl = wq((0 - yi) / h)
    n = len(yi)
    A = np.zeros((n + 1, n + 1))
    A[:n, :n] = S.T @ ((V * kp)[:, None] * B)
    A[:n, n] = c
    A[n, :n] = wfl
    rhs = np.concatenate([-r, [0]])
    sol = np.linalg.lstsq(A, rhs, rcond=1e-12)[0]
    du = sol[:n]
    p = ps + kp * (B @ du)
    out = dict(Y=Y, p=p, err=layer_err(Y, p), r=r, yi=yi, cond=np.linalg.cond(A),
               res=np.abs(A @ sol - rhs).max() / (rho * g * h))
    return out


def table(ops, label, ppas=(2, 3), **kw):
    rows = {}
    for ppa in ppas:
        tops, inner, bot, res = [], [], [], []
        for j in range(8):
            o = solve(ppa, j, ops, **kw)
            tops.append(o['err'][-1] * 100); inner.append(np.abs(o['err'][1:-1]).max() * 100)
            bot.append(o['err'][0] * 100); res.append(o['res'])
        rows[ppa] = tops
        print('%-10s ppa%d top%%: %s | max|1..14| %.2f | max|bottom| %.2f | solve resid %.1e' % (
            label, ppa, ' '.join('%6.2f' % t for t in tops), max(inner), max(np.abs(bot)), max(res)))
    return rows


if __name__ == '__main__':
    for shift in [False, True]:
        print('shift', shift)
        table(ops_apic, 'apic', shift=shift)
        table(ops_mls, 'mls', shift=shift)


def solve_nl(ppa, j, ops=ops_apic, shift=True, it=8, pfun=None, Bop=None):
    """Nonlinear static solve from the UNLOADED state (the engine's start):
    unknown nodal displacements u, J_p = exp((B u)_p) (so J-1 lies in the range of the strain
    operator, as in the engine), p = p(J); node balance S^T V p(J) = g W^T m, floor
    constraint sum_i w_i(0) u_i = 0 with reaction lam*c (ghost weights).
    Particles at the exact final positions x = Y + U (shift) or at Y.
    pfun(J, W, V) optionally maps J to the pressure used in the force (e.g. J-bar)."""
    Y, x, yi, dx, ps, Jex = setup(ppa, j, shift)
    W, B, S = ops(x, yi, dx)
    if Bop is not None:
        B = Bop(x, yi, dx)
    act = W.sum(0) > 0
    W, B, S, yi = W[:, act], B[:, act], S[:, act], yi[act]
    n = len(yi)
    m = rho * dx
    c = ghostw(yi, dx, ops)
    wfl = wq((0 - yi) / h)
    load = g * m * W.sum(0)

    def F(z):
        u, lam = z[:n], z[n]
        J = np.exp(B @ u)
        V = dx * J
        pp = press(J) if pfun is None else pfun(J, W, V)
        return np.concatenate([S.T @ (V * pp) + lam * c - load, [wfl @ u / h]]), J, pp

    z = np.zeros(n + 1)
    for k in range(it):
        R, J, pp = F(z)
        # analytic-ish Jacobian by finite differences (small system)
        A = np.zeros((n + 1, n + 1))
        for q in range(n + 1):
            dz = np.zeros(n + 1); dz[q] = 1e-9 if q < n else 1e-3
            A[:, q] = (F(z + dz)[0] - R) / dz[q]
        z = z - np.linalg.lstsq(A, R, rcond=1e-12)[0]
    R, J, pp = F(z)
    preport = press(J)
    return dict(Y=Y, p=preport, pf=pp, err=layer_err(Y, preport), res=np.abs(R[:n]).max() / (rho * g * h),
                yi=yi, u=z[:n], cond=np.linalg.cond(A))


def table_nl(ops, label, ppas=(2, 3), quiet=False, **kw):
    rows = {}
    for ppa in ppas:
        tops, inner, bot, res = [], [], [], []
        for j in range(8):
            o = solve_nl(ppa, j, ops, **kw)
            tops.append(o['err'][-1] * 100); inner.append(np.abs(o['err'][1:-1]).max() * 100)
            bot.append(o['err'][0] * 100); res.append(o['res'])
        rows[ppa] = (tops, max(inner), max(np.abs(bot)))
        if not quiet:
            print('%-10s ppa%d top%%: %s | max|1..14| %.2f | max|bottom| %.2f | resid %.1e' % (
                label, ppa, ' '.join('%6.2f' % t for t in tops), max(inner), max(np.abs(bot)), max(res)))
    return rows
