#version 330
// The measured material under point and directional lights (#defines from the
// renderer: BTF_KIND 0 none / 1 pca / 2 svd, PS 0/1, PBR 0/1 (the fitted glTF
// material of pbr.glsl), MDF 0/1 (mdf.glsl, mdf_shadow.glsl),
// SHADOWS 0/1, MDF_SHADOWS 0/1, AMBIENT 0/1 (mdf_shadow.glsl), PEM 0/1 (lights
// may be partial environment maps), N_LIGHTS (this
// program's number of lights, ≥ 1); with a BTF
// COMPONENTS (c) and, for the VIEW and LIGHT tables, _METHOD (0 nearest-k,
// 1 barycentric), _K (neighbours blended) and _CANDIDATES (per lookup cell)).
//
// Every direction is taken to the fragment's tangent frame (x along +u, y along
// +v, z the normal): the sample frame of the measurement, where θ, φ are defined.
//
// Loop lengths are compile-time constants and nothing branches on data: a
// software rasteriser runs every side of a branch with masked lanes anyway,
// and unrolls fixed loops into straight code. So every texture fetch is in
// uniform control flow and may take its level of detail from the implicit
// derivatives (cheaper than textureGrad with explicit ones).

// Blend, safe_normalize, tangent_frame and the blend_* lookups.
#include "directions.glsl"
#if PBR == 1
#include "pbr.glsl"
#endif
#if MDF == 1
#include "mdf.glsl"
#include "mdf_shadow.glsl"
#endif

in vec3 v_position;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
out vec4 frag;

uniform vec3 eye;              // camera position (perspective)
uniform vec3 toward_camera;    // unit, for an orthographic camera
uniform bool orthographic;
uniform float uv_scale;        // 1 / tile_mm: sample repeats per UV unit
uniform vec4 light_place[N_LIGHTS];   // xyz position (w = 1) or direction to the light (w = 0)
uniform vec3 light_emission[N_LIGHTS];

#if BTF_KIND > 0
uniform sampler2DArray view_cells;
uniform sampler2DArray light_cells;
uniform sampler2D light_cosines; // cos θ of each measured light, floored (a texel each)
uniform int n_table_lights;    // measured light directions
uniform sampler2D btf_weights; // pca: row slot·n_table_lights + light; svd: row slot; c/4 RGBA

Blend blend_view(vec3 q) {
#if VIEW_METHOD == 1
    return blend_barycentric(view_cells, VIEW_CANDIDATES, q);
#elif VIEW_K == 1
    return blend_nearest_one(view_cells, VIEW_CANDIDATES, q);
#else
    return blend_nearest(view_cells, VIEW_CANDIDATES, VIEW_K, q);
#endif
}

Blend blend_light(vec3 q) {
#if LIGHT_METHOD == 1
    Blend b = blend_barycentric(light_cells, LIGHT_CANDIDATES, q);
#elif LIGHT_K == 1
    Blend b = blend_nearest_one(light_cells, LIGHT_CANDIDATES, q);
#else
    Blend b = blend_nearest(light_cells, LIGHT_CANDIDATES, LIGHT_K, q);
#endif
    return carry_light_cosine(b, light_cosines, q);
}
#endif

#if BTF_KIND > 0
// Per group (pca: a view slot, svd: a light) its images' values, CHANNELS per
// texel each, packed four to a texel: value v of group g is component v % 4 of
// layer g·PACKED + v / 4 (render/core/textures.py).
uniform sampler2DArray btf_images;
#endif

#if BTF_KIND == 1
// Σ_l E_l Σ_j ω_j (mean_j Σ_m τ_lm + Σ_k γ_ljk B_jk), γ_ljk = Σ_m τ_lm p_{j, i_lm, k}
// (seed 000 eq. (3), (5)): the light sums go into per-slot RGB coefficients
// first, so each slot costs its ⌈CHANNELS·(c + 1)/4⌉ texture fetches however
// many lights there are. Images k = 4g…4g + 3 (image c is the mean) fill
// texels CHANNELS·g … CHANNELS·g + CHANNELS − 1 of their slot: a group's four
// coefficients are used up by its own fetches. A light below the horizon has E_l = 0.
vec3 shade_btf(vec2 st, Blend view, Blend lights[N_LIGHTS], vec3 irradiance[N_LIGHTS]) {
    vec3 mean_coef = vec3(0.0);
    for (int l = 0; l < N_LIGHTS; ++l) mean_coef += irradiance[l] * dot(lights[l].w, vec4(1.0));
    vec3 total = vec3(0.0);
    for (int j = 0; j < VIEW_K; ++j) {
        int slot = view.idx[j];
        vec3 slot_rgb = vec3(0.0);
        for (int g = 0; g <= COMPONENTS / 4; ++g) {
            vec4 red = vec4(0.0), green = vec4(0.0), blue = vec4(0.0);
            if (4 * g < COMPONENTS) {
                for (int l = 0; l < N_LIGHTS; ++l) {
                    for (int m = 0; m < LIGHT_K; ++m) {
                        vec3 e = irradiance[l] * lights[l].w[m];
                        int row = slot * n_table_lights + lights[l].idx[m];
                        vec4 p = texelFetch(btf_weights, ivec2(g, row), 0);
                        red += e.r * p;
                        green += e.g * p;
                        blue += e.b * p;
                    }
                }
            }
            vec3 coef[4];  // RGB factor of images 4g…4g + 3
            for (int q = 0; q < 4; ++q)
                coef[q] = 4 * g + q == COMPONENTS ? mean_coef : vec3(red[q], green[q], blue[q]);
            for (int t = 0; t < CHANNELS; ++t) {
                if (CHANNELS * g + t < PACKED) {
                    vec4 texel = texture(btf_images, vec3(st, slot * PACKED + CHANNELS * g + t));
                    for (int q = 0; q < 4; ++q) {
                        int v = 4 * t + q;  // value within the group: image 4g + v / CHANNELS
                        if (4 * g + v / CHANNELS <= COMPONENTS) {
#if CHANNELS == 1
                            slot_rgb += coef[v] * texel[q];
#else
                            slot_rgb[v % 3] += coef[v / 3][v % 3] * texel[q];
#endif
                        }
                    }
                }
            }
        }
        total += view.w[j] * slot_rgb;
    }
    return total;
}
#endif

#if BTF_KIND == 2
// Σ_l E_l Σ_m τ_lm Σ_k (Σ_j ω_j W_jk) E_k(x, y, l_m) (seed 001 §5).
vec3 shade_btf(vec2 st, Blend view, Blend lights[N_LIGHTS], vec3 irradiance[N_LIGHTS]) {
    float omega[COMPONENTS];  // the view slots' blended weight of each eigen image
    for (int k4 = 0; k4 < (COMPONENTS + 3) / 4; ++k4) {
        vec4 blended = vec4(0.0);
        for (int j = 0; j < VIEW_K; ++j)
            blended += view.w[j] * texelFetch(btf_weights, ivec2(k4, view.idx[j]), 0);
        for (int q = 0; q < 4; ++q)
            if (4 * k4 + q < COMPONENTS) omega[4 * k4 + q] = blended[q];
    }
    vec3 total = vec3(0.0);
    for (int l = 0; l < N_LIGHTS; ++l) {
        for (int m = 0; m < LIGHT_K; ++m) {
            int light = lights[l].idx[m];
            vec3 light_rgb = vec3(0.0);
            for (int p = 0; p < PACKED; ++p) {
                vec4 texel = texture(btf_images, vec3(st, light * PACKED + p));
                for (int q = 0; q < 4; ++q) {
                    int v = 4 * p + q;
#if CHANNELS == 1
                    if (v < COMPONENTS) light_rgb += vec3(omega[v] * texel[q]);
#else
                    if (v < 3 * COMPONENTS) light_rgb[v % 3] += omega[v / 3] * texel[q];
#endif
                }
            }
            total += irradiance[l] * lights[l].w[m] * light_rgb;
        }
    }
    return total;
}
#endif

#if PS == 1
uniform sampler2D ps_albedo;
uniform sampler2D ps_normals;      // sample frame = tangent frame
uniform float specular;            // Blinn–Phong weight
uniform float shininess;
#endif

#if PEM == 1
// Partial environment maps (render/pem/regions.py, render/pem/renderer.py): light l is a
// median-cut region when it has texels. light_texels[l]: first and count of its
// texels at the Lambert level, first and count at the level of the specular lobe;
// entry i of pem_texels is texel 2i (direction) and 2i + 1 (light Σ L Δω) in row order.
uniform sampler2D pem_texels;
uniform ivec4 light_texels[N_LIGHTS];
uniform float light_spread[N_LIGHTS];  // the region's shadow taps' spacing, scene units
#define SPREAD(l) max(light_spread[l] / shadow_offset[l], 1.0)
#else
#define SPREAD(l) 1.0
#endif

#if PEM == 1 && PS == 1
// Σ over texels first … first + count − 1 above the surface's horizon (normal `surface`:
// a sheet is lit from its front only) of their light × (n·l)⁺, or (lobe) × (n·h)^s where
// n·l > 0; the normals, the view and the texels' directions in the scene frame.
vec3 texel_sum(int first, int count, vec3 surface, vec3 n, vec3 view, bool lobe) {
    int width = textureSize(pem_texels, 0).x;
    vec3 total = vec3(0.0);
    for (int i = first; i < first + count; ++i) {
        ivec2 at = ivec2((2 * i) % width, (2 * i) / width);
        vec3 d = texelFetch(pem_texels, at, 0).xyz;
        float cos_in = dot(n, d);
        if (cos_in <= 0.0 || dot(surface, d) <= 0.0) continue;
        float weight = cos_in;
        if (lobe) weight = pow(max(dot(n, safe_normalize(d + view, vec3(0.0))), 0.0), shininess);
        total += weight * texelFetch(pem_texels, at + ivec2(1, 0), 0).rgb;
    }
    return total;
}

// Region l's light on the bumped normal n of a surface of normal `surface` (seed 002
// eq. (5)): its visibility (the shadow
// map's, from the region's irradiance over its emission; 1 where its direction is below
// the horizon, out of the map's reach) × its texels at the Lambert level × the albedo
// (under a BTF, which holds the diffuse shading, none) + at the lobe's level × specular.
vec3 region_light(int l, vec3 irradiance, float height, vec3 surface, vec3 n, vec3 view,
                  vec3 albedo) {
    vec3 emission = light_emission[l];
    float visible = height > 0.0 ? dot(irradiance, vec3(1.0)) / max(dot(emission, vec3(1.0)),
                                                                   1e-30) : 1.0;
    vec3 light = specular * texel_sum(light_texels[l].z, light_texels[l].w, surface, n, view,
                                      true);
#if BTF_KIND == 0
    light += albedo * texel_sum(light_texels[l].x, light_texels[l].y, surface, n, view, false);
#endif
    return visible * light;
}
#endif

#if SHADOWS == 1
uniform sampler2DShadow shadow_maps;       // atlas: light l's depth map is tile l of shadow_tiles
uniform mat4 light_view_proj[N_LIGHTS];
uniform float shadow_offset[N_LIGHTS];   // scene size of one shadow-map texel
uniform int shadow_tiles;
uniform float shadow_size;                 // texels per tile side

// Fraction of light l reaching p: 5×5 percentage-closer filtering of the
// light's depth map (each tap itself bilinear), so shadow edges are soft; the taps
// are SPREAD(l) texels apart (1, or wider for an extended light). The point is
// moved towards the light by what the surface's slope in the map adds over the
// kernel's radius (moving along the light ray does not move it in the map), and
// off the surface by a texel: no self-shadowing acne.
float lit_fraction(int l, vec3 p, vec3 n, vec3 to_light) {
    float cos_in = clamp(dot(n, to_light), 0.05, 1.0);
    float tan_in = sqrt(1.0 - cos_in * cos_in) / cos_in;
    float texel = shadow_offset[l];
    float spread = SPREAD(l);
    vec3 moved = p + n * texel + to_light * texel * (1.0 + 3.0 * spread * tan_in);
    vec4 clip = light_view_proj[l] * vec4(moved, 1.0);
    if (clip.w <= 0.0) return 1.0;
    vec3 s = clip.xyz / clip.w * 0.5 + 0.5;
    if (any(lessThan(s, vec3(0.0))) || any(greaterThan(s, vec3(1.0)))) return 1.0;
    float lo = 0.5 / shadow_size;
    float sum = 0.0;
    for (int dy = -2; dy <= 2; ++dy) {
        for (int dx = -2; dx <= 2; ++dx) {
            vec2 tap = clamp(s.xy + spread * vec2(dx, dy) / shadow_size, vec2(lo), vec2(1.0 - lo));
            tap.x = (tap.x + float(l)) / float(shadow_tiles);
            sum += texture(shadow_maps, vec3(tap, s.z));
        }
    }
    return sum / 25.0;
}
#endif

void main() {
    vec3 n = safe_normalize(v_normal, vec3(0.0, 0.0, 1.0));
    vec3 to_eye = orthographic ? toward_camera : safe_normalize(eye - v_position, n);
    // Two-sided: the back of a surface shows the material turned over about its
    // tangent (a rigid turn: the frame (t, −b, −n) stays right-handed).
    if (!gl_FrontFacing) n = -n;
    mat3 to_local = tangent_frame(n, v_tangent);

    vec2 st = v_uv * uv_scale;
    vec3 view_local = to_local * to_eye;

    vec3 irradiance[N_LIGHTS];
    vec3 light_local[N_LIGHTS];
#if MDF_SHADOWS == 1
    vec3 shadow_point = mesostructure_point(v_position, to_eye, st, view_local);
#else
    vec3 shadow_point = v_position;
#endif
#if AMBIENT == 1
    vec3 shadowed = vec3(0.0);  // Σ of the lights' irradiance that their shadows hold back
#endif
    for (int l = 0; l < N_LIGHTS; ++l) {
        irradiance[l] = vec3(0.0);
        vec3 to_light;
        vec3 e = light_emission[l];
        if (light_place[l].w > 0.5) {
            vec3 d = light_place[l].xyz - v_position;
            float r2 = max(dot(d, d), 1e-6);
            to_light = d * inversesqrt(r2);
            e /= r2;
        } else {
            to_light = safe_normalize(light_place[l].xyz, vec3(0.0, 0.0, 1.0));
        }
        light_local[l] = to_local * to_light;
        if (light_local[l].z <= 0.0) continue;  // below the horizon: no light, never NaN
        float lit = 1.0;
#if SHADOWS == 1
        lit = lit_fraction(l, shadow_point, n, to_light);
#endif
#if AMBIENT == 1
        // What a shadow holds back is the irradiance the light would bring, E cos θ_l:
        // it fades to nothing towards the horizon as the lit side's shading does, and
        // a surface facing away is unlit, not shadowed.
        shadowed += e * (light_local[l].z * (1.0 - lit));
#endif
        irradiance[l] = e * lit;
    }

    vec3 colour = vec3(0.0);
#if BTF_KIND > 0
    Blend view = blend_view(view_local);
    Blend lights[N_LIGHTS];
    for (int l = 0; l < N_LIGHTS; ++l) lights[l] = blend_light(light_local[l]);
    colour += shade_btf(st, view, lights, irradiance);
#endif
#if PBR == 1
    for (int l = 0; l < N_LIGHTS; ++l) colour += irradiance[l] * shade_pbr(st, view_local, light_local[l]);
#endif
#if AMBIENT == 1
    // In shadow the ambient term (seed 001 §4.2): a of what each shadow holds back comes
    // back as a uniform sky of radiance a · E cos θ_l / π.
    colour += (ambient / 3.14159265) * shadowed * ambient_term(st, view);
#endif
#if PEM == 1 && PS == 1
    mat3 to_world = transpose(to_local);
#endif
#if PS == 1
    // Bump mapping (seed 004): the measured normal, in the tangent frame, bends the
    // shading normal. Alone: Lambert + Blinn–Phong. Under a BTF, whose normtextures
    // already hold the diffuse shading, only the specular lobe is added.
    vec3 bump = texture(ps_normals, st).xyz;
    vec3 bumped = safe_normalize(bump, vec3(0.0, 0.0, 1.0));
    vec3 albedo = texture(ps_albedo, st).rgb;
    for (int l = 0; l < N_LIGHTS; ++l) {
#if PEM == 1
        if (light_texels[l].y + light_texels[l].w > 0) {
            colour += region_light(l, irradiance[l], light_local[l].z, n, to_world * bumped,
                                   to_eye, albedo);
            continue;
        }
#endif
        if (irradiance[l] == vec3(0.0)) continue;
        float cos_in = dot(bumped, light_local[l]);
        if (cos_in <= 0.0) continue;
        vec3 h = safe_normalize(light_local[l] + view_local, bumped);
        float lobe = specular > 0.0 ? specular * pow(max(dot(bumped, h), 0.0), shininess) : 0.0;
#if BTF_KIND == 0
        colour += irradiance[l] * (albedo * cos_in + lobe);
#else
        colour += irradiance[l] * lobe;
#endif
    }
#endif
    frag = vec4(colour, 1.0);
}
