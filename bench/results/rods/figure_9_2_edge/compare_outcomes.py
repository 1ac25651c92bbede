# Outcome changes between stability sweeps: python3 compare_outcomes.py NEW.csv OLD.csv [OLDER_OVERRIDDEN_BY_NEXT.csv ...]
import csv,sys
def load(p):
    d={}
    for r in csv.DictReader(open(p)):
        d[(r['combo'],r['value'].strip('"'),float(r['dt']))]=(r['outcome'],float(r['max_strain']) if r['max_strain'] else None)
    return d
new=load(sys.argv[1]); olds=[load(p) for p in sys.argv[2:]]
old={}
for o in olds: old.update(o)
ch=0; same=0; strain_same=0
for k in sorted(new):
    if k not in old: continue
    a,b=old[k],new[k]
    if a[0]!=b[0]:
        ch+=1; print('CHANGED', k, a, '->', b)
    else:
        same+=1
        if a[1]==b[1]: strain_same+=1
print(f'{ch} outcomes changed, {same} same ({strain_same} with the same largest strain)')
