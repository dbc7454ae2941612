#version 330
// A compressed BTF under an environment (seed 000 §5.3, eq. (10)–(11)), with the
// renderer's #defines COEF_WIDTH (texels per row of env_coef),
// CHANNELS (1 grey, 3 RGB), PACKED (texture layers per view slot or, for a global
// SVD, per light) and SVD_COMPONENTS (a global SVD's c; 0 for a per-view PCA).
//
// Per-view PCA: T_j = f · (u_0j m_j + Σ_k u_kj B_kj) per view slot j. Global SVD:
// T = f · Σ_i g_i Σ_k ω_k E_k(l_i), ω_k = Σ_j w_j W_jk (seed 001 §5), one g_i (RGB)
// per measured light. The coefficients u or g are
// blended from the triangle's three vertices; view slots blended per fragment by
// the rule of rig.geometry (nearest-k Shepard or barycentric), every table entry
// scanned (a few dozen view slots). The back of a surface gets no light: its
// coefficients hold the hemisphere in front.

in vec3 v_position;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
in vec3 v_bary;
flat in ivec3 v_ids;
out vec4 frag;

uniform vec3 eye;
uniform vec3 toward_camera;
uniform bool orthographic;
uniform float uv_scale;
uniform float exposure;          // f
uniform sampler2D env_coef;      // RGB: texel ((vertex·n_slots + slot)·(c + 1) + k)
uniform int n_slots;             // view slots of the material (a global SVD: its lights)
uniform int components;          // c (a global SVD: 0, one g per light)
// The point-light renderer's packed BTF (render/core/textures.py): a slot's images,
// basis 0…c − 1 then the mean, CHANNELS values each, four values to a texel;
// value v of slot j is component v % 4 of layer j·PACKED + v / 4.
uniform sampler2DArray btf_images;
uniform sampler2D view_table;    // nearest-k: (x, y, z, slot); barycentric: 4 rows per triangle
uniform int view_rows;           // table entries (directions or triangles)
uniform int view_method;         // 0 nearest-k, 1 barycentric
uniform int view_k;

vec3 safe_normalize(vec3 v, vec3 fallback) {
    float len2 = dot(v, v);
    return len2 > 1e-24 ? v * inversesqrt(len2) : fallback;
}

vec3 coefficient(int vertex, int slot, int k) {
    int i = (vertex * n_slots + slot) * (components + 1) + k;
    return texelFetch(env_coef, ivec2(i % COEF_WIDTH, i / COEF_WIDTH), 0).rgb;
}

vec3 blended(int slot, int k) {
    return v_bary.x * coefficient(v_ids.x, slot, k) + v_bary.y * coefficient(v_ids.y, slot, k)
         + v_bary.z * coefficient(v_ids.z, slot, k);
}

// The k nearest valid view slots (ties to the lower index), Shepard weights
// 1/angle², weight one at a slot's own direction: rig.geometry.nearest_directions.
void nearest_slots(vec3 q, out ivec4 slots, out vec4 w) {
    vec4 best = vec4(-2.0);
    ivec4 idx = ivec4(0);
    for (int t = 0; t < view_rows; ++t) {
        float c = dot(q, texelFetch(view_table, ivec2(0, t), 0).xyz);
        if (c > best.w) {
            best.w = c;
            idx.w = t;
            if (best.w > best.z) { best.zw = best.wz; idx.zw = idx.wz; }
            if (best.z > best.y) { best.yz = best.zy; idx.yz = idx.zy; }
            if (best.y > best.x) { best.xy = best.yx; idx.xy = idx.yx; }
        }
    }
    vec4 angle;
    for (int m = 0; m < 4; ++m) {
        vec4 entry = texelFetch(view_table, ivec2(0, idx[m]), 0);
        slots[m] = int(entry.w + 0.5);
        angle[m] = atan(length(cross(q, entry.xyz)), dot(q, entry.xyz));
    }
    w = vec4(0.0);
    if (angle.x <= 1e-6) { w.x = 1.0; return; }
    for (int m = 0; m < 4; ++m) w[m] = m < view_k ? 1.0 / (angle[m] * angle[m]) : 0.0;
    w /= dot(w, vec4(1.0));
}

// The spherical triangle holding q (largest smallest weight), its gnomonic
// barycentric weights: rig.geometry.barycentric_weights.
void barycentric_slots(vec3 q, out ivec4 slots, out vec4 w) {
    float best = -1e30;
    vec3 weights = vec3(1.0, 0.0, 0.0);
    int tri = 0;
    for (int t = 0; t < view_rows; ++t) {
        vec3 b = vec3(dot(texelFetch(view_table, ivec2(0, 4 * t), 0).xyz, q),
                      dot(texelFetch(view_table, ivec2(0, 4 * t + 1), 0).xyz, q),
                      dot(texelFetch(view_table, ivec2(0, 4 * t + 2), 0).xyz, q));
        float low = min(b.x, min(b.y, b.z));
        if (low > best) { best = low; weights = b; tri = t; }
    }
    slots = ivec4(ivec3(texelFetch(view_table, ivec2(0, 4 * tri + 3), 0).xyz + 0.5), 0);
    weights = max(weights, vec3(0.0));
    float total = weights.x + weights.y + weights.z;
    w = vec4(total > 0.0 ? weights / total : vec3(1.0, 0.0, 0.0), 0.0);
}

#if SVD_COMPONENTS > 0
uniform sampler2D btf_weights;   // row slot: W_jk, four k to a texel

// Σ_i g_i Σ_k ω_k E_k(st, l_i) over the measured lights whose g is not zero.
vec3 shade_svd(ivec4 slots, vec4 w, vec2 st, vec2 sx, vec2 sy) {
    float omega[SVD_COMPONENTS];
    for (int k4 = 0; k4 < (SVD_COMPONENTS + 3) / 4; ++k4) {
        vec4 blend = vec4(0.0);
        for (int j = 0; j < 4; ++j) blend += w[j] * texelFetch(btf_weights, ivec2(k4, slots[j]), 0);
        for (int q = 0; q < 4; ++q)
            if (4 * k4 + q < SVD_COMPONENTS) omega[4 * k4 + q] = blend[q];
    }
    vec3 total = vec3(0.0);
    for (int light = 0; light < n_slots; ++light) {
        vec3 g = blended(light, 0);
        if (g == vec3(0.0)) continue;
        vec3 light_rgb = vec3(0.0);
        for (int p = 0; p < PACKED; ++p) {
            vec4 texel = textureGrad(btf_images, vec3(st, light * PACKED + p), sx, sy);
            for (int q = 0; q < 4; ++q) {
                int v = 4 * p + q;
#if CHANNELS == 1
                if (v < SVD_COMPONENTS) light_rgb += vec3(omega[v] * texel[q]);
#else
                if (v < 3 * SVD_COMPONENTS) light_rgb[v % 3] += omega[v / 3] * texel[q];
#endif
            }
        }
        total += g * light_rgb;
    }
    return total;
}
#endif

void main() {
    if (!gl_FrontFacing) { frag = vec4(0.0, 0.0, 0.0, 1.0); return; }
    vec3 n = safe_normalize(v_normal, vec3(0.0, 0.0, 1.0));
    vec3 to_eye = orthographic ? toward_camera : safe_normalize(eye - v_position, n);
    float hand = v_tangent.w < 0.0 ? -1.0 : 1.0;
    vec3 t = v_tangent.xyz - n * dot(n, v_tangent.xyz);
    vec3 any_side = abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
    t = safe_normalize(t, safe_normalize(cross(any_side, n), vec3(1.0, 0.0, 0.0)));
    vec3 b = hand * cross(n, t);
    vec3 q = transpose(mat3(t, b, n)) * to_eye;
    q = safe_normalize(vec3(q.xy, max(q.z, 0.0)), vec3(0.0, 0.0, 1.0));

    ivec4 slots;
    vec4 w;
    if (view_method == 1) barycentric_slots(q, slots, w);
    else nearest_slots(q, slots, w);

    vec2 st = v_uv * uv_scale;
    vec2 sx = dFdx(st);
    vec2 sy = dFdy(st);
#if SVD_COMPONENTS > 0
    vec3 total = shade_svd(slots, w, st, sx, sy);
#else
    vec3 total = vec3(0.0);
    for (int j = 0; j < 4; ++j) {
        if (w[j] == 0.0) continue;
        int slot = slots[j];
        vec3 slot_rgb = vec3(0.0);
        vec3 coef = vec3(0.0);  // of the image value v belongs to
        for (int p = 0; p < PACKED; ++p) {
            vec4 texel = textureGrad(btf_images, vec3(st, slot * PACKED + p), sx, sy);
            for (int q = 0; q < 4; ++q) {
                // Value v is of image v / CHANNELS: basis k < c weighs by U's k + 1, the mean by U's 0.
                int v = 4 * p + q;
                int image = v / CHANNELS;
                if (image > components) break;
                if (v % CHANNELS == 0) coef = blended(slot, image == components ? 0 : image + 1);
#if CHANNELS == 1
                slot_rgb += coef * texel[q];
#else
                slot_rgb[v % 3] += coef[v % 3] * texel[q];
#endif
            }
        }
        total += w[j] * slot_rgb;
    }
#endif
    frag = vec4(exposure * total, 1.0);
}
