"""One BLAS thread for the command line (imported by :mod:`thermoskin.cli` before numpy).

Thermoskin's matrices are small (a 5-state network, an MPC of a few dozen variables), so a
second BLAS thread never helps; OpenBLAS's idle threads, though, spin for a while after each
call and took a quarter of a second of the other core from ``observe``'s reading and writing
threads on a 1 h log. A value the user set in the environment is kept.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
