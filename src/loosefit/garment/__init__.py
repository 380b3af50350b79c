"""Garments at rest: parametric skirts (:mod:`.skirt`), OBJ import/export with UV atlases
(:mod:`.obj`) and pure mesh checks (:mod:`.mesh_checks`). Each produces or inspects a
:class:`loosefit.types.GarmentTemplate` (vertices, faces, per-corner UVs, waistband)."""
