"""API: what generated clients are made of: the sync and async client bases, typed accessors and
register descriptors, a client's working parts (:mod:`.machinery`), clients built from a spec at run
time and the identity check."""
