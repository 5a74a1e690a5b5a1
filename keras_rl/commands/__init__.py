"""One module per command: its arguments (``add_parser``) and its work; ``keras_rl/cli.py`` joins them."""
