#!/bin/sh
# Irregular pinned at 1M vertices, one thread: iterative solvers, then CHOLMOD with SA+PPCG (split for memory, as B1/B2).
OMP_NUM_THREADS=1 /tmp/weft_bk bench linear --examples pinned --tessellations irregular --sizes 1000 --solvers diag_pcg sa_ppcg sa_ppcg_flat --steps 2 --threads 1 --out ../M5-irregular-1M-iterative > iterative.log 2>&1
OMP_NUM_THREADS=1 /tmp/weft_bk bench linear --examples pinned --tessellations irregular --sizes 1000 --solvers cholmod sa_ppcg --steps 2 --threads 1 --out ../M5-irregular-1M-direct > direct.log 2>&1
