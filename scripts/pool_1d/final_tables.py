"""Per-offset worst-layer |error| (all 16 layers, %) of the 1D dynamic engine replica (dyn2.run),
for the baseline and the corrections; engine offset j = grid moved by -j h/8.
usage: final_tables.py NAME   (one correction per call, < 30 s each)"""
import sys, numpy as np, dyn2
C = {
 'baseline':      (dict(fgrad='apic'), dict(fgrad='mls')),
 'jbar_node':     (dict(fgrad='apic_avg'), dict(fgrad='mls_avg')),
 'ls_rate':       (dict(fgrad='apic_ls'), dict(fgrad='mls_ls')),
 'gimp_const':    (dict(fgrad='apic', force='domconst', mass='bar', dom='cp'), dict(fgrad='mls', force='domconst', mass='bar', dom='cp')),
 'domlin':        (dict(fgrad='apic', force='domlin', mass='bar', dom='cp', pgrad='gridls'), dict(fgrad='mls', force='domlin', mass='bar', dom='cp', pgrad='gridls')),
 'domlin_state':  (dict(fgrad='apic', force='domlin', mass='bar', dom='cp', pgrad='state'), dict(fgrad='mls', force='domlin', mass='bar', dom='cp', pgrad='state')),
 'domlin+jbar':   (dict(fgrad='apic_avg', force='domlin', mass='bar', dom='cp', pgrad='gridls'), dict(fgrad='mls_avg', force='domlin', mass='bar', dom='cp', pgrad='gridls')),
 'domlin+ls':     (dict(fgrad='apic_ls', force='domlin', mass='bar', dom='cp', pgrad='gridls'), dict(fgrad='mls_ls', force='domlin', mass='bar', dom='cp', pgrad='gridls')),
 'domlin_u':      (dict(fgrad='apic', force='domlin', mass='bar', dom='u', pgrad='gridls'), dict(fgrad='mls_ls', force='domlin', mass='bar', dom='u', pgrad='gridls')),
}
name = sys.argv[1]
for kind, kw in zip(['APIC', 'MLS'], C[name]):
    for ppa in (2, 3):
        worst, top, inner, floor, vm = [], [], [], [], []
        for j in range(8):
            o = dyn2.run(ppa, j, **kw)
            e = np.abs(o['err']) * 100
            worst.append(e.max()); top.append(o['err'][-1] * 100); inner.append(e[1:-1].max()); floor.append(e[0]); vm.append(o['vmax'])
        print('%-12s %-4s ppa%d worst: %s | top(signed): %s | max L1-14 %.2f | max L0 %.2f | vmax %.0e' % (
            name, kind, ppa, ' '.join('%5.2f' % w for w in worst), ' '.join('%6.2f' % t for t in top),
            max(inner), max(floor), max(vm)), flush=True)
