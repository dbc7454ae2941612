#version 330
// The shadow-map pass of a BTF + MDF surface (seed 001 §4.2): world position and
// normal on to shadow_mdf.frag, which pushes the depth to the mesostructure's base.
uniform mat4 view_proj;
in vec3 in_position;
in vec3 in_normal;
out vec3 v_position;
out vec3 v_normal;

void main() {
    v_position = in_position;
    v_normal = in_normal;
    gl_Position = view_proj * vec4(in_position, 1.0);
}
