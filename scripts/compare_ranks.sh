#!/bin/bash
# Every scene in scenes/ for one frame on 1 and 2 ranks (one thread each), the frames compared
# particle by particle with h5py against the bound of docs/distributed.md ("The same answer").
# Usage: scripts/compare_ranks.sh [OUTDIR]   (needs build/bin/mpm and build/lib/libmpm_stvk.so)
cd "$(dirname "$0")/.."
out=${1:-/tmp/mpm_compare_ranks}; mkdir -p $out
for s in scenes/*.yaml; do
  n=$(basename $s .yaml); extra=""
  [ $n = plugin_stvk ] && extra="--plugin build/lib/libmpm_stvk.so"
  OMP_NUM_THREADS=1 build/bin/mpm run $s --frames 1 --threads 1 --quiet --force $extra --out $out/$n/one > $out/$n.one.log 2>&1
  OMP_NUM_THREADS=1 mpirun --allow-run-as-root --oversubscribe -np 2 build/bin/mpm run $s --frames 1 --threads 1 --quiet --force $extra --out $out/$n/two > $out/$n.two.log 2>&1
  /usr/bin/python3 - $out/$n <<'PY'
import h5py, numpy as np, sys, os
d=sys.argv[1]; m=[0.0]*4
try:
  for f in (0,1):
    a=h5py.File(d+'/one/frame_%05d.h5'%f,'r'); b=h5py.File(d+'/two/frame_%05d.h5'%f,'r')
    assert (a['id'][:]==b['id'][:]).all()
    m=[max(m[0],np.linalg.norm(a['position'][:]-b['position'][:],axis=1).max()),max(m[1],np.linalg.norm(a['velocity'][:]-b['velocity'][:],axis=1).max()),max(m[2],np.abs(a['J'][:]-b['J'][:]).max()),max(m[3],np.linalg.norm(a['velocity'][:],axis=1).max())]
  rel=m[1]/m[3] if m[3]>0 else 0
  ok = m[0]<5e-7 and m[2]<1e-5 and m[1]<=1e-5*m[3]
  print('%-18s dx %.2g m  dv %.2g m/s  vmax %.3g m/s  dv/vmax %.2g  dJ %.2g  %s'%(os.path.basename(d),m[0],m[1],m[3],rel,m[2],'within bound' if ok else 'OUTSIDE BOUND'))
except Exception as e:
  print(os.path.basename(d),'ERROR',e)
PY
done
