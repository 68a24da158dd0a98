"""Sanity checks on a generated OUTDIR (reads only the generator's own output)."""
import sys, os, json, glob
import numpy as np
out = sys.argv[1]
def load(p):
    with open(p) as f:
        hdr = [next(f) for _ in range(5)]
    d = np.loadtxt(p, delimiter=',', skiprows=5)
    return hdr, d
bad = 0
for tp in sorted(glob.glob(os.path.join(out, 'truth', 'case_*.json'))):
    tr = json.load(open(tp)); c = tr['case']
    files = sorted(os.listdir(os.path.join(out, c)))
    nstep = sum(r['starts_with_step'] for r in tr['recordings'] if r['experiment'] != 'id')
    nexp = len(tr['recordings']) - 1
    durs = []
    for r in tr['recordings']:
        hdr, d = load(os.path.join(out, c, r['file']))
        ok = (hdr[0].strip() == '# sample_time: 0.001' and hdr[4].strip() == 't,u,y'
              and np.all(np.diff(d[:, 0]) > 0) and abs(d[0, 0]) < 1e-12
              and np.all(np.abs(d[:, 1]) <= 100 + 1e-9))
        if r['starts_with_step'] and r['experiment'] != 'id':
            ok &= d[0, 1] == 0.0 and np.max(np.abs(np.diff(d[:, 1]))) > 10
        bad += not ok
        durs.append(round(len(d) / 1000, 1))
        if r['experiment'] == 'id':
            ypp = d[:, 2].max() - d[:, 2].min()
    mags = '; '.join('%s/%s %s=%.4g' % (e['kind'][:6], e['form'], e['magnitude_name'], e['magnitude'])
                     for e in tr['effects']) or 'none'
    print('%s id_pp=%.2fV W=%.3f h=%.2f dens=%-10s exps=%d step_start=%d durs=%s | %s' % (
        c, ypp, tr['base']['major_loop_width_fraction'], tr['base']['irr_fraction_h'],
        tr['base']['density'], nexp, nstep, durs, mags))
print('format/step problems:', bad)
