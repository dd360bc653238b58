// Baked global illumination drawn with Gouraud shading (TinyRender's `gi` pass, FORMAT.md §6).
//
// Each vertex carries its baked linear RGB radiance; the rasteriser interpolates it
// (perspective-correct) across the triangle. The colour target is an sRGB format, so the
// hardware encodes linear → sRGB on store and clamps to [0, 1], which is what TinyRender's
// real-time output holds (FORMAT.md §8).

struct Uniforms {
    view_proj: mat4x4<f32>,
    // x: 1 for false colour, 0 for radiance; y, z: log10 of the luminance mapped to the ends
    // of the false-colour ramp; w: unused.
    params: vec4<f32>,
};

@group(0) @binding(0) var<uniform> u: Uniforms;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec3<f32>,
};

@vertex
fn vs_main(@location(0) position: vec3<f32>, @location(1) color: vec3<f32>) -> VertexOut {
    var out: VertexOut;
    out.clip = u.view_proj * vec4<f32>(position, 1.0);
    out.color = color;
    return out;
}

// Turbo colour map (Google, 2019), polynomial fit by Ruofei Du; input in [0, 1], output
// sRGB-encoded.
fn turbo(x: f32) -> vec3<f32> {
    let t = clamp(x, 0.0, 1.0);
    let k4 = vec4<f32>(1.0, t, t * t, t * t * t);
    let k2 = k4.zw * k4.z;
    let r = dot(vec4<f32>(0.13572138, 4.61539260, -42.66032258, 132.13108234), k4)
        + dot(vec2<f32>(-152.94239396, 59.28637943), k2);
    let g = dot(vec4<f32>(0.09140261, 2.19418839, 4.84296658, -14.18503333), k4)
        + dot(vec2<f32>(4.27729857, 2.82956604), k2);
    let b = dot(vec4<f32>(0.10667330, 12.64194608, -60.58204836, 110.36276771), k4)
        + dot(vec2<f32>(-89.90310912, 27.34824973), k2);
    return clamp(vec3<f32>(r, g, b), vec3<f32>(0.0), vec3<f32>(1.0));
}

// sRGB-encoded → linear (the exact sRGB EOTF), so that the sRGB target shows the ramp as designed.
fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    if (u.params.x > 0.5) {
        // Luminance (Rec. 709) on a log scale; zero and negative map to the bottom of the ramp.
        let y = dot(in.color, vec3<f32>(0.2126, 0.7152, 0.0722));
        let l = log2(max(y, 1e-30)) * 0.30102999566; // log10
        let span = max(u.params.z - u.params.y, 1e-6);
        return vec4<f32>(srgb_to_linear(turbo((l - u.params.y) / span)), 1.0);
    }
    return vec4<f32>(in.color, 1.0);
}
