"""Garments at rest: parametric skirts (:mod:`.skirt`), OBJ import/export with UV atlases
(:mod:`.obj`), pure mesh checks (:mod:`.mesh_checks`) and a sequence's quality figures
(:mod:`.quality`). Each produces or inspects a
:class:`loosefit.types.GarmentTemplate` (vertices, faces, per-corner UVs, waistband)."""
