#version 330
// The speed floor: one filtered fetch of one texture layer, no shading.
uniform sampler2DArray btf_images;
uniform float uv_scale;
in vec3 v_position;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
out vec4 frag;

void main() {
    frag = vec4(texture(btf_images, vec3(v_uv * uv_scale, 0.0)).rgb, 1.0);
}
