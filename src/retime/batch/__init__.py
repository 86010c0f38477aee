"""``retime batch``: many clips through the single-clip commands on Dask distributed.

Layers: :mod:`.jobs` finds the clips (folders, files, jobs files), :mod:`.manifest` remembers which
finished with which inputs and options, :mod:`.run` drives the Dask cluster and :mod:`.summary`
writes summary.csv and index.html. Nothing in retime imports this package; it sits on the CLI.
"""
