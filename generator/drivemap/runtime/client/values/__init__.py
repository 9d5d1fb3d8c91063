"""Values: raw words <-> engineering values (word and byte order, scaling, steps, enums, bit-field
records) and what a person sees of them. Knows nothing of requests, buses or clients; the simulator
uses it too."""
