// Mesostructure-aware shadows and the ambient term (seed 001 §4.2), included after
// mdf.glsl with #defines MDF_SHADOWS 0/1 and AMBIENT 0/1 (render/points/ambient.py).

#if MDF_SHADOWS == 1
uniform float mdf_scale;   // s: scene units per mm of the sample (tile_mm / sample_mm)
uniform float mdf_depth;   // d_max: the deepest seen mesostructure point, mm of the sample
uniform float max_slant;   // 1 / cos of the grazing clamp (render.mdf.GRAZING_DEG)

// p' = p − s·D(x, y, v)·v, where the view ray through p meets the mesostructure:
// the point whose macro shadow counts (to_eye: unit, scene frame; view_local: tangent
// frame). A blend of view slots can reach below the base (a steeper slot's longer D);
// D is held to d_max / cos θ_v there, so p' never passes the depth the shadow maps hold.
vec3 mesostructure_point(vec3 p, vec3 to_eye, vec2 st, vec3 view_local) {
    float slant = min(1.0 / max(view_local.z, 1e-6), max_slant);
    float d = min(mdf_distance_mm(st, view_local), mdf_depth * slant);
    return p - to_eye * (mdf_scale * d);
}
#endif

#if AMBIENT == 1
uniform sampler2DArray ambient_images;   // L_a per view slot, BTF units × sr
uniform float ambient;                   // the skylight fraction a of each light's irradiance

// L_a(x, y, v) blended over the BTF's view slots as the BTF is.
vec3 ambient_term(vec2 st, Blend view) {
    vec3 total = vec3(0.0);
    for (int j = 0; j < VIEW_K; ++j)
        total += view.w[j] * texture(ambient_images, vec3(st, float(view.idx[j]))).rgb;
    return total;
}
#endif
