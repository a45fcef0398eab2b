"""Seeing a solved scene: its states as steps (:mod:`.states`), the fields on them (:mod:`.fields`),
pictures of the deformed sections (:mod:`.shapes`), the animation (:mod:`.animation`) and the
ParaView time series (:mod:`.export`). matplotlib and meshio are imported inside the functions
that need them."""
