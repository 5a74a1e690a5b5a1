"""One module per post: its typed config (every hyperparameter and quirk switch citing the
post), its env, and how its agent is assembled from the shared parts. The quirks of a post
live in its module: ``pendulum.py`` (post 000), ``mountaincar.py`` (post 001),
``cartpole.py`` (post 003)."""
