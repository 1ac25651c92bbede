import json,statistics
def load(d):
    rows=[json.loads(l) for l in open(d+'/bench_hair.jsonl')]
    return [r for r in rows if 'sp_alternations' in r]
a=load('ball_1000_10ms_defaults_stopped_at_24'); b=load('ball_1000_10ms_full_sp_inner_1_sp_anderson_5_sp_max_1000')
n=min(len(a),len(b))
for name,st in (('defaults',a[:n]),('one sweep + mix',b[:n])):
    u=[r['gs_residual'] for r in st if r.get('gs_unconverged')]
    print(f"| {name} | {n} | {sum(r['wall_s'] for r in st):.0f} s | {sum(r['gs_sweeps'] for r in st)/n:.0f} | {sum(r['sp_alternations'] for r in st)/n:.0f} | {len(u)} | {statistics.median(u):.1e}, {max(u):.1e} | {100*max(r['strain'] for r in st):.2f} % | {sum(r['contacts'] for r in st)/n:.0f} |")
