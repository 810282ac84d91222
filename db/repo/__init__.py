"""Query functions, one module per aggregate.

Every function takes a ``Session`` first, adds/flushes/selects, and never commits: the
caller owns the transaction (``with factory.begin() as session:``).
"""
