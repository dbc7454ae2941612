#version 330
// World-space mesh (the model matrix is the identity): positions, shading frame, UVs.
uniform mat4 view_proj;
in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;
in vec4 in_tangent;
out vec3 v_position;
out vec3 v_normal;
out vec4 v_tangent;
out vec2 v_uv;
// The same depth as depth.vert's: the renderer's depth pre-pass must match exactly.
invariant gl_Position;

void main() {
    v_position = in_position;
    v_normal = in_normal;
    v_tangent = in_tangent;
    v_uv = in_uv;
    gl_Position = view_proj * vec4(in_position, 1.0);
}
