"""The levels, each declared once: what it needs, how its geometry, image, quality and
product tree are made (:class:`levels.makers.base.LevelMaker`).

One module per level (``level1a`` … ``level3``), the steps several levels share in
``steps`` (the 2A grids that level 2's checkpoints also read, the model level 2 refines
that level 3 also uses), and the vocabulary in ``base``. The registry
(:mod:`levels.registry`) names them; the driver (:mod:`levels.process`) plans and runs them.
"""

__all__: list[str] = []
