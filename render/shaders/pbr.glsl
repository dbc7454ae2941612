// The glTF PBR fit of a material (rig.material.evaluate_pbr, line by line): metallic-
// roughness with metallic 0, KHR_materials_specular, _sheen (Charlie lobe and visibility,
// albedo scaling by the integrated table) and _anisotropy. Shared by the renderer's pbr
// layer (included by surface.frag) and the web viewer (rig export web).
// pbr_maps layers (rig.material.pbr_layers): 0 base colour, roughness; 1 sheen colour,
// sheen roughness; 2 normal, specular; 3 cos φ, sin φ, anisotropy, specular colour.
uniform sampler2DArray pbr_maps;
uniform sampler2D sheen_lut;  // E(cos θ, r): rows cos θ 0…1, columns r 0.07…1, texelFetch
uniform float pbr_white;      // the BTF value a white diffuse texel lit frontally has

float sheen_e(float mu, float r) {
    ivec2 size = textureSize(sheen_lut, 0);  // x: roughness cells, y: cos cells
    float x = clamp(mu, 0.0, 1.0) * float(size.y - 1);
    float y = (clamp(r, 0.07, 1.0) - 0.07) / 0.93 * float(size.x - 1);
    int x0 = min(int(floor(x)), size.y - 2);
    int y0 = min(int(floor(y)), size.x - 2);
    float fx = x - float(x0), fy = y - float(y0);
    float top = mix(texelFetch(sheen_lut, ivec2(y0, x0), 0).r,
                    texelFetch(sheen_lut, ivec2(y0 + 1, x0), 0).r, fy);
    float bottom = mix(texelFetch(sheen_lut, ivec2(y0, x0 + 1), 0).r,
                       texelFetch(sheen_lut, ivec2(y0 + 1, x0 + 1), 0).r, fy);
    return clamp(mix(top, bottom, fx), 0.0, 1.0);
}

float sheen_ell(float x, float r) {
    float t = (1.0 - r) * (1.0 - r);
    float a = mix(21.5473, 25.3245, t), b = mix(3.82987, 3.32435, t);
    float c = mix(0.19823, 0.16801, t), d = mix(-1.97760, -1.27393, t);
    float e = mix(-4.32054, -4.85967, t);
    return a / (1.0 + b * pow(max(x, 0.0), c)) + d * x + e;
}

float sheen_lambda(float c, float r) {
    c = abs(c);
    return c < 0.5 ? exp(sheen_ell(c, r)) : exp(2.0 * sheen_ell(0.5, r) - sheen_ell(1.0 - c, r));
}

// π f(l, v) N·L in the BTF's units for view v and light l in the tangent frame.
vec3 shade_pbr(vec2 st, vec3 v, vec3 l) {
    const float PI = 3.14159265358979;
    vec4 p0 = texture(pbr_maps, vec3(st, 0.0)), p1 = texture(pbr_maps, vec3(st, 1.0));
    vec4 p2 = texture(pbr_maps, vec3(st, 2.0)), p3 = texture(pbr_maps, vec3(st, 3.0));
    vec3 base = p0.rgb, sheen = p1.rgb;
    float roughness = p0.a, sheen_r = clamp(p1.a, 0.07, 1.0), specular = p2.a;
    float spec_colour = p3.a, strength = p3.z;
    vec3 n = normalize(p2.xyz + vec3(0.0, 0.0, 1e-12));
    vec3 t = length(p3.xy) > 1e-12 ? vec3(normalize(p3.xy), 0.0) : vec3(1.0, 0.0, 0.0);
    vec3 b = vec3(-t.y, t.x, 0.0);
    float nl = dot(n, l), nv = dot(n, v);
    if (nl <= 0.0 || nv <= 0.0) return vec3(0.0);
    nl = clamp(nl, 1e-7, 1.0);
    nv = clamp(nv, 1e-7, 1.0);
    vec3 h = normalize(l + v);
    float nh = clamp(dot(n, h), 0.0, 1.0), vh = clamp(dot(v, h), 0.0, 1.0);
    float alpha = max(roughness * roughness, 1e-4);
    float at = mix(alpha, 1.0, strength * strength), ab = alpha, a2 = at * ab;
    vec3 f = vec3(ab * dot(t, h), at * dot(b, h), a2 * nh);
    float w2 = a2 / max(dot(f, f), 1e-30);
    float D = a2 * w2 * w2 / PI;
    float V = 0.5 / max(nl * length(vec3(at * dot(t, v), ab * dot(b, v), nv))
                        + nv * length(vec3(at * dot(t, l), ab * dot(b, l), nl)), 1e-7);
    float f0 = min(0.04 * spec_colour, 1.0) * specular;
    float F = f0 + (specular - f0) * pow(1.0 - vh, 5.0);
    float peak = max(sheen.r, max(sheen.g, sheen.b));
    float scaling = min(1.0 - peak * sheen_e(nv, sheen_r), 1.0 - peak * sheen_e(nl, sheen_r));
    float sin2 = max(1.0 - nh * nh, 0.0);
    float charlie = (2.0 + 1.0 / sheen_r) * pow(sin2, 0.5 / sheen_r) / (2.0 * PI)
        / max((1.0 + sheen_lambda(nv, sheen_r) + sheen_lambda(nl, sheen_r)) * 4.0 * nv * nl, 1e-7);
    vec3 radiance = scaling * (1.0 - F) * nl * base + PI * scaling * F * D * V * nl
                    + PI * charlie * nl * sheen;
    return pbr_white * radiance;
}
