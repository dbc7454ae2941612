#version 330
// Depth only, from a light: the shadow map pass.
uniform mat4 view_proj;
in vec3 in_position;

void main() {
    gl_Position = view_proj * vec4(in_position, 1.0);
}
