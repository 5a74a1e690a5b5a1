"""One agent skeleton (``skeleton.py``) and the small strategies the posts differ by:
when to train (``schedules.py``), what a transition stores (``transitions.py``) and how to
explore (``explorers.py``). Nothing here imports TensorFlow or torch."""
