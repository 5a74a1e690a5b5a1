"""Reading run folders back: multi-seed summaries, Keras-vs-PyTorch reports, statistics and
plots. Training code never imports this package (it is where matplotlib lives)."""
