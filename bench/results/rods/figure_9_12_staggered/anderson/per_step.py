import json,sys
for d in sys.argv[1:]:
    rows=[json.loads(l) for l in open(d+'/bench_hair.jsonl')]
    st=[r for r in rows if 'sp_alternations' in r]
    print(d)
    print('  alt ', [r['sp_alternations'] for r in st])
    print('  swp ', [r.get('gs_sweeps') for r in st])
    print('  res ', ['%.1e'%r.get('gs_residual',0) for r in st])
    print('  unc ', [r.get('gs_unconverged') for r in st])
    print('  wall', [round(r['wall_s'],1) for r in st], 'sum', round(sum(r['wall_s'] for r in st),1))
    print('  cont', [r.get('contacts') for r in st])
