"""Step-for-step eager mirrors of the posts' own code, kept as the yardstick.

They exist for parity tests (same weights, same batch: do we compute what the post
computed?) and for benchmarks (how much faster is the compiled path?). They are
deliberately slow: eager calls, ``get_weights``/``set_weights``, Python lists.
"""
