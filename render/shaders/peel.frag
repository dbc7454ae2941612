#version 330
// One step of a depth-peeling pass for mesostructure silhouettes (render/points/peel.py;
// seed 001 §4.1, Fig. 7), with mdf.glsl's #defines. BACK_FACES 1: the back faces
// of this layer (the ray leaves the object there) write (t_b, d_b) to peel_next;
// BACK_FACES 0: the front faces of this layer keep their depth, and set the hit mask,
// where the ray meets the mesostructure: t_f + d_f ≤ t_b − d_b. t is the distance
// along the pixel's ray from the eye, d = texture_scale · D (mm of the scene).

#include "directions.glsl"
#include "mdf.glsl"

in vec3 v_position;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
out vec4 peel;

uniform vec3 eye;
uniform vec3 toward_camera;    // unit
uniform bool orthographic;
uniform float uv_scale;        // 1 / tile_mm
uniform float texture_scale;   // tile_mm / sample_mm: mm of scene per mm of sample
uniform sampler2D peel_now;    // R: t of the previous layer's back face (−1e30 before the first)
#if BACK_FACES == 1
uniform sampler2D hit_mask;    // R > 0.5: an earlier layer's ray already hit (the stencil)
#else
uniform sampler2D peel_next;   // this layer's back face: R = t_b (1e30: none), G = d_b
#endif

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 ray = orthographic ? -toward_camera : safe_normalize(v_position - eye, -toward_camera);
    float t = orthographic ? dot(v_position - eye, ray) : length(v_position - eye);
    float previous = texelFetch(peel_now, px, 0).r;
    if (t <= previous + 1e-6 * abs(previous)) discard;  // peeled already
    // The cheap tests first: fragments dropped here skip the MDF lookup.
#if BACK_FACES == 1
    if (texelFetch(hit_mask, px, 0).r > 0.5) discard;
#else
    vec2 back = texelFetch(peel_next, px, 0).rg;
    if (t >= back.r) discard;               // beyond this layer's exit: a later layer's face
#endif
    // The view direction of the MDF points away from the surface: towards the eye at a
    // front face, along the ray at a back face (the ray leaves through it).
    vec3 n = safe_normalize(v_normal, vec3(0.0, 0.0, 1.0));
    vec3 away = BACK_FACES == 1 ? ray : -ray;
    float d = texture_scale * mdf_distance_mm(v_uv * uv_scale, tangent_frame(n, v_tangent) * away);
#if BACK_FACES == 1
    peel = vec4(t, d, 0.0, 1.0);
#else
    if (t + d > back.r - back.g) discard;   // the ray passes through the mesostructure
    peel = vec4(1.0);
#endif
}
