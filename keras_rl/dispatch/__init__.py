"""How a command's seeds reach the engines (above ``train/``, which it calls): ``options.py``
(``RunOptions``), ``jobs.py`` (``SeedJob``, in-process), ``pool_backend.py`` (a process pool),
``ray_backend.py`` (Ray), ``backends.py`` (which one), and the two callers that make jobs of their
own, ``sweep.py`` (grids) and ``compare_runs.py`` (both frameworks). The records they leave are
``runs/``'s, below ``train/``."""
