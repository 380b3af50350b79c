"""Pure geometry: skinning, normals, queries."""
