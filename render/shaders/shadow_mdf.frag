#version 330
// Seed 001 §4.2: the shadow map holds the depth of the mesostructure's base, not of
// the reference surface: z + d_max / cos θ_l along the light ray, so a surface never
// shadows its own mesostructure (the BTF already holds that self-shadowing) while
// other blockers still do. cos θ_l is clamped at max_slant (grazing light: the push
// would grow without bound). Both sides of a surface push away from the light.
uniform mat4 view_proj;
uniform vec4 light_place;   // xyz position (w = 1) or direction to the light (w = 0)
uniform float base_depth;   // s · d_max: the mesostructure's depth below the surface, scene units
uniform float max_slant;    // 1 / cos of the grazing clamp
in vec3 v_position;
in vec3 v_normal;

void main() {
    vec3 to_light = light_place.w > 0.5 ? light_place.xyz - v_position : light_place.xyz;
    float len2 = dot(to_light, to_light);
    to_light = len2 > 1e-24 ? to_light * inversesqrt(len2) : vec3(0.0, 0.0, 1.0);
    float n2 = dot(v_normal, v_normal);
    vec3 n = n2 > 1e-24 ? v_normal * inversesqrt(n2) : to_light;
    float slant = min(1.0 / max(abs(dot(n, to_light)), 1e-6), max_slant);
    vec4 clip = view_proj * vec4(v_position - to_light * base_depth * slant, 1.0);
    gl_FragDepth = clamp(clip.z / clip.w * 0.5 + 0.5, 0.0, 1.0);
}
