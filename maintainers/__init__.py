"""The maintainers' tools, apart from the package users install: the check's calibration
(``calibrate/``), the generated tables (``tables/``) and the manifest of committed run sets
(``manifest.py``), run from a checkout as ``python -m maintainers calibrate|tables|manifest``.
They read and regenerate the checkout's ``results/``; nothing in ``keras_rl`` imports them."""
