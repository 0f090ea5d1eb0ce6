"""What a person looks at after a run: ``ehw replay`` (the lifetime as a video, ``replay``) and
``ehw report`` (one self-contained ``report.html``, ``html``; its figures in ``figures``).

Both read only the run folder's files (``summary.json``, ``lifetime.npz`` of
``sim_world.recording``, ``config.toml``, ``sessions.json``, the PNGs; for a comparison
``compare.json``, ``compare.md``, ``compare.png``), so they work on a run made by any backend, in
this process or another. Imports ``cosim.paper``, ``sim_world``
(the recording's reader, the arena drawing), ``ga`` and ``base``.
"""
