"""Input and output: files in, files out, and the key paths that name a value in them.

``safe_yaml`` (YAML read with cpopt's own limits and messages), ``output`` (atomic writes, JSON
and CSV, output folders and their locks) and ``keypath`` (``motion.duration``-style paths into
nested data). The bottom layer: it imports nothing of cpopt outside ``cpopt.io``, so every other
layer may import it. The result types (``Solution``) are not here: they hold plans and
verifications, so they live with the application at the top (``cpopt.results``).
"""
