#version 330
// Depth only: the shadow map pass from a light, and the renderer's depth pre-pass.
uniform mat4 view_proj;
in vec3 in_position;
invariant gl_Position;  // the same depth as surface.vert's

void main() {
    gl_Position = view_proj * vec4(in_position, 1.0);
}
