"""The bottom floor every package may use: user errors, result files, run folders, checkpoints,
config files and the shared command-line flags.

``errors`` (``UserError`` and the one ``error:`` line), ``files`` (atomic writes, merged JSON),
``runs`` (run folders, locks, ``latest``), ``checkpoint`` (checksummed checkpoints),
``config_file`` (``--config run.toml``), ``options`` (the flags every run shares). Imports nothing
of the project.
"""
