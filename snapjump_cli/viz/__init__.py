"""Seeing a solved scene: its states as steps (:mod:`.states`), the fields on them (:mod:`.fields`),
pictures of the deformed sections (:mod:`.shapes`), the animation (:mod:`.animation`) and the
ParaView time series (:mod:`.export`), all of a command's files at once (:mod:`.outputs`), and the
figures of a ranked table and the p-V curve (:mod:`.figures`). matplotlib and meshio are imported
inside the functions that need them."""
