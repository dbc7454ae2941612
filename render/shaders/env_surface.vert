#version 330
// The mesh drawn triangle by triangle (corners unshared), so each fragment knows
// its triangle's three vertices and its barycentric coordinates: the per-vertex
// environment coefficients are blended across the triangle (seed 000 §5.3).
uniform mat4 view_proj;
in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;
in vec4 in_tangent;
in ivec3 in_ids;     // the triangle's three vertex indices
in vec3 in_corner;   // this corner's barycentric coordinates: (1,0,0), (0,1,0) or (0,0,1)
out vec3 v_position;
out vec3 v_normal;
out vec4 v_tangent;
out vec2 v_uv;
out vec3 v_bary;
flat out ivec3 v_ids;

void main() {
    v_position = in_position;
    v_normal = in_normal;
    v_tangent = in_tangent;
    v_uv = in_uv;
    v_bary = in_corner;
    v_ids = in_ids;
    gl_Position = view_proj * vec4(in_position, 1.0);
}
