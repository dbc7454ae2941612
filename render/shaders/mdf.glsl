// The mesostructure distance function (render/points/mdf.py), included after directions.glsl:
// D(x, y, v) in mm of the sample, one texture layer per view slot, blended over view
// slots with the BTF's own rule (MDF_VIEW_METHOD 0 nearest-k / 1 barycentric,
// MDF_VIEW_K neighbours, MDF_VIEW_CANDIDATES per lookup cell) and bilinear over texels.

uniform sampler2DArray mdf_distance;   // layer = view slot; unseen texels filled, grazing clamped
uniform sampler2DArray mdf_view_cells;

// D at texture coordinate st seen from view_local (the tangent frame, pointing away from
// the surface; below the horizon it is laid onto it, like every view lookup).
float mdf_distance_mm(vec2 st, vec3 view_local) {
#if MDF_VIEW_METHOD == 1
    Blend b = blend_barycentric(mdf_view_cells, MDF_VIEW_CANDIDATES, view_local);
#elif MDF_VIEW_K == 1
    Blend b = blend_nearest_one(mdf_view_cells, MDF_VIEW_CANDIDATES, view_local);
#else
    Blend b = blend_nearest(mdf_view_cells, MDF_VIEW_CANDIDATES, MDF_VIEW_K, view_local);
#endif
    float d = 0.0;
    for (int j = 0; j < MDF_VIEW_K; ++j)
        d += b.w[j] * texture(mdf_distance, vec3(st, float(b.idx[j]))).r;
    return d;
}
