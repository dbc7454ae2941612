// Tangent frames and direction lookups shared by the surface and the MDF shaders
// (included after the program's #version and #defines): blend a measured direction
// table at a query exactly as rig.geometry does, from the grids of render/core/lookup.py.

struct Blend { ivec4 idx; vec4 w; };

vec3 safe_normalize(vec3 v, vec3 fallback) {
    float len2 = dot(v, v);
    return len2 > 1e-24 ? v * inversesqrt(len2) : fallback;
}

// World → tangent frame (x along +u, y along +v, z the unit normal n): the sample
// frame of the measurement. tangent.w is the handedness; a tangent along n falls
// back on any direction across it.
mat3 tangent_frame(vec3 n, vec4 tangent) {
    float hand = tangent.w < 0.0 ? -1.0 : 1.0;
    vec3 t = tangent.xyz - n * dot(n, tangent.xyz);
    vec3 any_side = abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
    t = safe_normalize(t, safe_normalize(cross(any_side, n), vec3(1.0, 0.0, 0.0)));
    vec3 b = hand * cross(n, t);
    return transpose(mat3(t, b, n));
}

// ---- direction lookups (render/core/lookup.py builds the candidate grids) ----

ivec2 hemi_cell(vec3 d, int res) {
    vec3 a = abs(d);
    vec2 p = d.xy / (a.x + a.y + d.z);
    vec2 uv = vec2(p.x + p.y, p.x - p.y);
    return clamp(ivec2(floor((uv * 0.5 + 0.5) * float(res))), ivec2(0), ivec2(res - 1));
}

// q in the tangent frame; below the horizon it is laid onto it (θ = 90°).
vec3 on_hemisphere(vec3 q) {
    return safe_normalize(vec3(q.xy, max(q.z, 0.0)), vec3(0.0, 0.0, 1.0));
}

// The k nearest table directions of q (ties to the lower index) with Shepard
// weights 1/angle², exactly one at a table direction: rig.geometry.nearest_directions.
// A cell's `count` candidates (layer i: direction xyz, table index w), ascending,
// are ranked by cosine (the same order as by angle), the best four kept sorted
// in a vec4 without local arrays, which software rasterisers handle slowly.
Blend blend_nearest(sampler2DArray cells, int count, int k, vec3 q) {
    q = on_hemisphere(q);
    ivec2 cell = hemi_cell(q, textureSize(cells, 0).x);
    vec4 best = vec4(-2.0);
    ivec4 at = ivec4(0);  // the best four's places in the cell's list
    for (int i = 0; i < count; ++i) {
        float c = dot(q, texelFetch(cells, ivec3(cell, i), 0).xyz);
        if (c > best.w) {
            best.w = c;
            at.w = i;
            if (best.w > best.z) { best.zw = best.wz; at.zw = at.wz; }
            if (best.z > best.y) { best.yz = best.zy; at.yz = at.zy; }
            if (best.y > best.x) { best.xy = best.yx; at.xy = at.yx; }
        }
    }
    Blend b;
    b.idx = ivec4(0);
    vec4 inverse_sq = vec4(0.0);
    float nearest_angle = 0.0;
    for (int m = 0; m < k; ++m) {
        vec4 texel = texelFetch(cells, ivec3(cell, at[m]), 0);
        b.idx[m] = int(texel.w + 0.5);
        float angle = atan(length(cross(q, texel.xyz)), dot(q, texel.xyz));
        if (m == 0) nearest_angle = angle;
        inverse_sq[m] = 1.0 / max(angle * angle, 1e-30);
    }
    b.w = nearest_angle <= 1e-6 ? vec4(1.0, 0.0, 0.0, 0.0)
                                : inverse_sq / dot(inverse_sq, vec4(1.0));
    return b;
}

// k = 1: the nearest table direction alone, weight one (no angle needed).
Blend blend_nearest_one(sampler2DArray cells, int count, vec3 q) {
    q = on_hemisphere(q);
    ivec2 cell = hemi_cell(q, textureSize(cells, 0).x);
    float best = -2.0;
    float index = 0.0;
    for (int i = 0; i < count; ++i) {
        vec4 texel = texelFetch(cells, ivec3(cell, i), 0);
        float c = dot(q, texel.xyz);
        if (c > best) {
            best = c;
            index = texel.w;
        }
    }
    Blend b;
    b.idx = ivec4(int(index + 0.5), 0, 0, 0);
    b.w = vec4(1.0, 0.0, 0.0, 0.0);
    return b;
}

// The spherical triangle holding q, barycentric weights in its gnomonic
// projection: rig.geometry.barycentric_weights. A cell's `count` candidates
// take three layers each: the rows of the triangle's inverse (w_i = row_i · q),
// each with its corner's table index in w.
Blend blend_barycentric(sampler2DArray cells, int count, vec3 q) {
    q = on_hemisphere(q);
    ivec2 cell = hemi_cell(q, textureSize(cells, 0).x);
    float best = -1e30;
    vec3 weights = vec3(1.0, 0.0, 0.0);
    vec3 corners = vec3(0.0);
    for (int i = 0; i < count; ++i) {
        vec4 r0 = texelFetch(cells, ivec3(cell, 3 * i), 0);
        vec4 r1 = texelFetch(cells, ivec3(cell, 3 * i + 1), 0);
        vec4 r2 = texelFetch(cells, ivec3(cell, 3 * i + 2), 0);
        vec3 w = vec3(dot(r0.xyz, q), dot(r1.xyz, q), dot(r2.xyz, q));
        float low = min(w.x, min(w.y, w.z));
        if (low > best) {
            best = low;
            weights = w;
            corners = vec3(r0.w, r1.w, r2.w);
        }
    }
    Blend b;
    b.idx = ivec4(ivec3(corners + 0.5), 0);
    weights = max(weights, vec3(0.0));
    float total = weights.x + weights.y + weights.z;
    b.w = vec4(total > 0.0 ? weights / total : vec3(1.0, 0.0, 0.0), 0.0);
    return b;
}

// A light's blend carries the irradiance's cosine (rig.geometry.carry_light_cosine):
// each measured light's weight times cos θ_q / cos θ_i, with cos θ_i (floored on the
// CPU) read from texel (i, 0) of `cosines`. Exact at a measured light; zero at the horizon.
Blend carry_light_cosine(Blend b, sampler2D cosines, vec3 q) {
    float cos_q = on_hemisphere(q).z;
    for (int m = 0; m < 4; ++m)
        b.w[m] *= cos_q / texelFetch(cosines, ivec2(b.idx[m], 0), 0).r;
    return b;
}
