"""What the python back end owns: generated names, the names a generated client reserves, in-memory packages.
"""
