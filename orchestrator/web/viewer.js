// btfrig web viewer: the measured BTF (per-view PCA, the renderer's neighbour and blend
// rules) or its glTF PBR fit on a mesh, in plain WebGL2. Data: window.BTFRIG (this
// material, data.js), window.BTFRIG_MESHES (meshes.js) and window.BTFRIG_PBR_GLSL
// (shaders.js: the renderer's render/shaders/pbr.glsl), written by `rig export web`.
// Drag: orbit; shift-drag: move the light; the controls: mesh, BTF/PBR, exposure.
"use strict";

function decode(base64, Type) {
  const bytes = Uint8Array.from(atob(base64), (c) => c.charCodeAt(0));
  return new Type(bytes.buffer);
}

function direction(thetaDeg, phiDeg) {
  const t = (thetaDeg * Math.PI) / 180, p = (phiDeg * Math.PI) / 180;
  return [Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t)];
}

const VERTEX = `#version 300 es
in vec3 position; in vec3 normal; in vec4 tangent; in vec2 uv;
uniform mat4 view_projection;
out vec3 v_position; out vec3 v_normal; out vec4 v_tangent; out vec2 v_uv;
void main() {
  v_position = position; v_normal = normal; v_tangent = tangent; v_uv = uv;
  gl_Position = view_projection * vec4(position, 1.0);
}`;

function fragmentSource(m) {
  return `#version 300 es
precision highp float; precision highp int; precision highp sampler2DArray;
#define N_VIEWS ${m.views.length}
#define N_TABLE_LIGHTS ${m.lights.length}
#define COMPONENTS ${m.components}
#define LIGHT_COSINE_FLOOR ${m.light_cosine_floor.toFixed(6)}
in vec3 v_position; in vec3 v_normal; in vec4 v_tangent; in vec2 v_uv;
out vec4 frag;
uniform vec3 eye; uniform vec3 to_light; uniform float uv_scale; uniform float exposure;
uniform int mode;  // 0 BTF, 1 PBR
uniform vec3 view_dirs[N_VIEWS]; uniform float slot_valid[N_VIEWS];
uniform vec3 light_dirs[N_TABLE_LIGHTS];
uniform sampler2DArray btf;      // layer slot·(c + 1) + k, k = c the mean
uniform highp sampler2D weights; // row slot·n_lights + light, ⌈c/4⌉ RGBA
precision highp sampler2D;

vec3 safe_normalize(vec3 v, vec3 fallback) {
  float len2 = dot(v, v);
  return len2 > 1e-24 ? v * inversesqrt(len2) : fallback;
}
mat3 tangent_frame(vec3 n, vec4 tangent) {
  float hand = tangent.w < 0.0 ? -1.0 : 1.0;
  vec3 t = tangent.xyz - n * dot(n, tangent.xyz);
  vec3 any_side = abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  t = safe_normalize(t, safe_normalize(cross(any_side, n), vec3(1.0, 0.0, 0.0)));
  return transpose(mat3(t, hand * cross(n, t), n));
}
vec3 on_hemisphere(vec3 q) { return safe_normalize(vec3(q.xy, max(q.z, 0.0)), vec3(0.0, 0.0, 1.0)); }

// The 4 nearest table directions (ties to the lower index), Shepard weights 1/angle²,
// exactly one at a table direction: rig.geometry.nearest_directions.
void nearest(vec3 q, bool views, out ivec4 idx, out vec4 w) {
  q = on_hemisphere(q);
  vec4 best = vec4(-2.0); idx = ivec4(0);
  int count = views ? N_VIEWS : N_TABLE_LIGHTS;
  for (int i = 0; i < count; ++i) {
    if (views && slot_valid[i] < 0.5) continue;
    vec3 d = views ? view_dirs[i] : light_dirs[i];
    float c = dot(q, d);
    if (c > best.w) {
      best.w = c; idx.w = i;
      if (best.w > best.z) { best.zw = best.wz; idx.zw = idx.wz; }
      if (best.z > best.y) { best.yz = best.zy; idx.yz = idx.zy; }
      if (best.y > best.x) { best.xy = best.yx; idx.xy = idx.yx; }
    }
  }
  vec4 inverse_sq = vec4(0.0); float nearest_angle = 0.0;
  for (int k = 0; k < 4; ++k) {
    if (best[k] < -1.5) continue;
    vec3 d = views ? view_dirs[idx[k]] : light_dirs[idx[k]];
    float angle = atan(length(cross(q, d)), dot(q, d));
    if (k == 0) nearest_angle = angle;
    inverse_sq[k] = 1.0 / max(angle * angle, 1e-30);
  }
  w = nearest_angle <= 1e-6 ? vec4(1.0, 0.0, 0.0, 0.0) : inverse_sq / dot(inverse_sq, vec4(1.0));
}

vec3 shade_btf(vec2 st, vec3 view_local, vec3 light_local) {
  ivec4 vi, li; vec4 vw, lw;
  nearest(view_local, true, vi, vw);
  nearest(light_local, false, li, lw);
  // A light's blend carries the irradiance's cosine (rig.geometry.carry_light_cosine).
  float cos_q = on_hemisphere(light_local).z;
  for (int m = 0; m < 4; ++m) lw[m] *= cos_q / max(light_dirs[li[m]].z, LIGHT_COSINE_FLOOR);
  vec3 total = vec3(0.0);
  for (int j = 0; j < 4; ++j) {
    if (vw[j] == 0.0) continue;
    int slot = vi[j];
    vec3 slot_rgb = texture(btf, vec3(st, float(slot * (COMPONENTS + 1) + COMPONENTS))).rgb
                    * dot(lw, vec4(1.0));
    for (int g = 0; g < (COMPONENTS + 3) / 4; ++g) {
      vec4 gamma = vec4(0.0);
      for (int m = 0; m < 4; ++m)
        gamma += lw[m] * texelFetch(weights, ivec2(g, slot * N_TABLE_LIGHTS + li[m]), 0);
      for (int q = 0; q < 4; ++q) {
        int k = 4 * g + q;
        if (k < COMPONENTS)
          slot_rgb += gamma[q] * texture(btf, vec3(st, float(slot * (COMPONENTS + 1) + k))).rgb;
      }
    }
    total += vw[j] * slot_rgb;
  }
  return total;
}

${window.BTFRIG_PBR_GLSL}

vec3 srgb(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
}

void main() {
  vec3 n = safe_normalize(v_normal, vec3(0.0, 0.0, 1.0));
  vec3 to_eye = safe_normalize(eye - v_position, n);
  if (!gl_FrontFacing) n = -n;
  mat3 to_local = tangent_frame(n, v_tangent);
  vec2 st = v_uv * uv_scale;
  vec3 view_local = to_local * to_eye, light_local = to_local * to_light;
  vec3 colour = vec3(0.0);
  if (light_local.z > 0.0)
    colour = mode == 0 ? shade_btf(st, view_local, light_local) : shade_pbr(st, view_local, light_local);
  frag = vec4(srgb(colour * exp2(exposure)), 1.0);
}`;
}

function compile(gl, type, source) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, source);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
  return shader;
}

function textureArray(gl, data, size, layers, internal, format, unit, mipmaps) {
  const texture = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0 + unit);
  gl.bindTexture(gl.TEXTURE_2D_ARRAY, texture);
  gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, internal, size, size, layers, 0, format, gl.HALF_FLOAT, data);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_S, gl.REPEAT);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_T, gl.REPEAT);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  if (mipmaps) {
    gl.generateMipmap(gl.TEXTURE_2D_ARRAY);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.LINEAR_MIPMAP_LINEAR);
  } else {
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  }
  return texture;
}

function dataTexture(gl, data, width, height, internal, format, unit) {
  const texture = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0 + unit);
  gl.bindTexture(gl.TEXTURE_2D, texture);
  gl.texImage2D(gl.TEXTURE_2D, 0, internal, width, height, 0, format, gl.FLOAT, data);
  for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
  return texture;
}

function lookAt(eye, target) {
  const sub = (a, b) => a.map((x, i) => x - b[i]);
  const norm = (a) => { const l = Math.hypot(...a); return a.map((x) => x / l); };
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const f = norm(sub(target, eye));
  let side = cross(f, [0, 0, 1]);
  if (Math.hypot(...side) < 1e-6) side = cross(f, [0, 1, 0]);
  side = norm(side);
  const up = cross(side, f);
  return [side, up, f.map((x) => -x), [-dot(side, eye), -dot(up, eye), dot(f, eye)]];
}

function viewProjection(camera, aspect, near, far) {
  const [s, u, b, t] = lookAt(camera.eye, camera.target);
  const view = [s[0], u[0], b[0], 0, s[1], u[1], b[1], 0, s[2], u[2], b[2], 0, t[0], t[1], t[2], 1];
  const c = 1 / Math.tan((camera.fov * Math.PI) / 360);
  const proj = [c / aspect, 0, 0, 0, 0, c, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, (2 * far * near) / (near - far), 0];
  const out = new Float32Array(16);
  for (let col = 0; col < 4; ++col)
    for (let row = 0; row < 4; ++row)
      for (let k = 0; k < 4; ++k) out[col * 4 + row] += proj[k * 4 + row] * view[col * 4 + k];
  return out;
}

function start() {
  const m = window.BTFRIG, meshes = window.BTFRIG_MESHES;
  const canvas = document.getElementById("view");
  const gl = canvas.getContext("webgl2", { preserveDrawingBuffer: true, antialias: false });
  if (!gl) { document.getElementById("status").textContent = "this browser has no WebGL2"; return; }
  const mipmaps = gl.getExtension("EXT_color_buffer_float") !== null;
  const program = gl.createProgram();
  gl.attachShader(program, compile(gl, gl.VERTEX_SHADER, VERTEX));
  gl.attachShader(program, compile(gl, gl.FRAGMENT_SHADER, fragmentSource(m)));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
  gl.useProgram(program);
  const u = (name) => gl.getUniformLocation(program, name);
  const n = m.size, c = m.components;
  // RGB16F cannot render into its own mipmaps (WebGL2 has no colour-renderable RGB16F):
  // the BTF is sampled bilinearly, without a mipmap chain.
  textureArray(gl, decode(m.btf, Uint16Array), n, m.views.length * (c + 1), gl.RGB16F, gl.RGB, 0, false);
  dataTexture(gl, decode(m.weights, Float32Array), Math.ceil(c / 4), m.views.length * m.lights.length, gl.RGBA32F, gl.RGBA, 1);
  textureArray(gl, decode(m.pbr, Uint16Array), n, 4, gl.RGBA16F, gl.RGBA, 2, mipmaps);  // rig.material.pbr_layers
  dataTexture(gl, decode(m.sheen_lut.values, Float32Array), m.sheen_lut.roughness, m.sheen_lut.cos, gl.R32F, gl.RED, 3);
  gl.uniform1i(u("btf"), 0); gl.uniform1i(u("weights"), 1); gl.uniform1i(u("pbr_maps"), 2); gl.uniform1i(u("sheen_lut"), 3);
  gl.uniform3fv(u("view_dirs"), m.views.flat()); gl.uniform1fv(u("slot_valid"), m.slot_valid);
  gl.uniform3fv(u("light_dirs"), m.lights.flat()); gl.uniform1f(u("pbr_white"), m.white);
  gl.enable(gl.DEPTH_TEST);

  const buffers = {};
  function useMesh(name) {
    const mesh = meshes[name];
    for (const [attribute, size] of [["position", 3], ["normal", 3], ["tangent", 4], ["uv", 2]]) {
      const location = gl.getAttribLocation(program, attribute);
      const buffer = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      gl.bufferData(gl.ARRAY_BUFFER, decode(mesh[attribute], Float32Array), gl.STATIC_DRAW);
      gl.enableVertexAttribArray(location);
      gl.vertexAttribPointer(location, size, gl.FLOAT, false, 0, 0);
    }
    const faces = decode(mesh.faces, Uint32Array);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, faces, gl.STATIC_DRAW);
    buffers.count = faces.length;
    buffers.radius = mesh.radius;
  }

  const home = m.cameras;
  const state = { mesh: m.mesh, mode: 0, exposure: m.exposure_ev, light: m.light_deg.slice(), orbit: null };
  const meshSelect = document.getElementById("mesh");
  function setMesh(name) {
    state.mesh = name;
    meshSelect.value = name;
    useMesh(name);
    const cam = home[name];
    const offset = cam.eye.map((x, i) => x - cam.target[i]);
    const distance = Math.hypot(...offset);
    state.orbit = { target: cam.target, distance, fov: cam.fov,
      theta: (Math.acos(offset[2] / distance) * 180) / Math.PI, phi: (Math.atan2(offset[1], offset[0]) * 180) / Math.PI };
  }
  function draw() {
    const o = state.orbit;
    const eye = direction(o.theta, o.phi).map((x, i) => o.target[i] + o.distance * x);
    const far = o.distance + 2 * buffers.radius, near = Math.max(far * 1e-4, o.distance - 2 * buffers.radius);
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.clearColor(0, 0, 0, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.uniformMatrix4fv(u("view_projection"), false, viewProjection({ eye, target: o.target, fov: o.fov }, canvas.width / canvas.height, near, far));
    gl.uniform3fv(u("eye"), eye);
    gl.uniform3fv(u("to_light"), direction(state.light[0], state.light[1]));
    gl.uniform1f(u("uv_scale"), 1 / m.sample_mm);
    gl.uniform1f(u("exposure"), state.exposure);
    gl.uniform1i(u("mode"), state.mode);
    gl.drawElements(gl.TRIANGLES, buffers.count, gl.UNSIGNED_INT, 0);
  }

  let last = null;
  canvas.addEventListener("pointerdown", (e) => { last = [e.clientX, e.clientY, e.shiftKey]; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener("pointerup", () => { last = null; });
  canvas.addEventListener("pointermove", (e) => {
    if (last === null) return;
    const dx = e.clientX - last[0], dy = e.clientY - last[1];
    if (last[2] || e.shiftKey) {
      state.light[1] -= dx * 0.5;
      state.light[0] = Math.min(89, Math.max(0, state.light[0] + dy * 0.5));
    } else {
      state.orbit.phi -= dx * 0.5;
      state.orbit.theta = Math.min(179, Math.max(1, state.orbit.theta - dy * 0.5));
    }
    last = [e.clientX, e.clientY, last[2]];
    draw();
  });
  const exposure = document.getElementById("exposure");
  exposure.value = state.exposure;
  exposure.addEventListener("input", () => { state.exposure = Number(exposure.value); draw(); });
  const mode = document.getElementById("mode");
  mode.addEventListener("click", () => { state.mode = 1 - state.mode; mode.textContent = state.mode ? "PBR fit" : "measured BTF"; draw(); });
  for (const name of Object.keys(meshes)) meshSelect.add(new Option(name, name, false, name === m.mesh));
  meshSelect.addEventListener("change", () => { setMesh(meshSelect.value); draw(); });
  setMesh(state.mesh);
  draw();
  const error = gl.getError();
  if (error !== gl.NO_ERROR) throw new Error(`WebGL error ${error} while drawing`);
  window.btfrigViewer = { state, draw, setMesh };
  document.body.dataset.ready = "1";
  document.getElementById("status").textContent = "";
}

window.addEventListener("load", start);
