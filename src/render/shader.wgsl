// Lit triangles with per-vertex colour, and unlit lines, drawn offscreen.

struct Uniforms {
    clip_from_world: mat4x4<f32>,
    // Direction towards the light in the world frame (w unused).
    light_dir: vec4<f32>,
};

@group(0) @binding(0) var<uniform> u: Uniforms;

struct MeshIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
};

struct MeshOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
};

@vertex
fn vs_mesh(v: MeshIn) -> MeshOut {
    var out: MeshOut;
    out.clip = u.clip_from_world * vec4<f32>(v.position, 1.0);
    out.normal = v.normal;
    out.color = v.color;
    return out;
}

@fragment
fn fs_mesh(v: MeshOut) -> @location(0) vec4<f32> {
    // Two-sided Lambert with an ambient floor: gamma-encoded colours in,
    // gamma-encoded colours out (the texture is Rgba8Unorm).
    let n = normalize(v.normal);
    let diffuse = abs(dot(n, normalize(u.light_dir.xyz)));
    let shade = 0.35 + 0.65 * diffuse;
    return vec4<f32>(v.color.rgb * shade, v.color.a);
}

struct LineIn {
    @location(0) position: vec3<f32>,
    @location(1) color: vec4<f32>,
};

struct LineOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec4<f32>,
};

@vertex
fn vs_line(v: LineIn) -> LineOut {
    var out: LineOut;
    out.clip = u.clip_from_world * vec4<f32>(v.position, 1.0);
    out.color = v.color;
    return out;
}

@fragment
fn fs_line(v: LineOut) -> @location(0) vec4<f32> {
    return v.color;
}
