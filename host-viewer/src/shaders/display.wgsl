// The path-traced view: shows the accumulation (linear mean radiance, one texel per film
// pixel, and the relative standard error in alpha) with an exposure and the sRGB transfer
// function, or the relative error in false colour.
//
// The film is drawn 1:1 when the window has the film's size (each fragment reads the texel
// under its centre; no filtering), else scaled to fit, nearest texel, centred.
//
// The sRGB encoding is computed here, in f32, as `ember render` writes its PNG preview
// (linear_to_srgb, then round half up to 8 bits). On an sRGB target the exact linear value of
// that 8-bit code is returned, which the hardware encodes back to the same code; on a UNORM
// target the code itself.

struct Params {
    // film width, height; window width, height (pixels)
    size: vec4<f32>,
    // x: exposure multiplier; y: 1 for the relative-error view; z: 1 if the target is sRGB
    mode: vec4<f32>,
    // x, y: log10 of the relative errors at the ends of the false-colour ramp
    error_range: vec4<f32>,
};

@group(0) @binding(0) var<uniform> u: Params;
@group(0) @binding(1) var film: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the viewport.
    let p = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(p * 2.0 - 1.0, 0.0, 1.0);
}

fn linear_to_srgb(v: vec3<f32>) -> vec3<f32> {
    let c = clamp(v, vec3<f32>(0.0), vec3<f32>(1.0));
    let lo = 12.92 * c;
    let hi = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}

fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

// Turbo colour map (Google, 2019), polynomial fit by Ruofei Du; sRGB-encoded output.
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

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let film_size = u.size.xy;
    let window = u.size.zw;
    let scale = min(window.x / film_size.x, window.y / film_size.y);
    let offset = 0.5 * (window - film_size * scale);
    let f = (pos.xy - offset) / scale;
    var code = vec3<f32>(0.0);
    if (all(f >= vec2<f32>(0.0)) && all(f < film_size)) {
        let texel = textureLoad(film, vec2<i32>(floor(f)), 0);
        if (u.mode.y > 0.5) {
            if (texel.a > 0.0) {
                let l = log2(texel.a) * 0.30102999566; // log10
                let span = max(u.error_range.y - u.error_range.x, 1e-6);
                code = turbo((l - u.error_range.x) / span);
            } else if (texel.a == 0.0) {
                code = turbo(0.0);
            }
            // Undefined (negative: under two samples, or a black pixel) stays black.
        } else {
            code = linear_to_srgb(texel.rgb * u.mode.x);
        }
        // 8-bit code, rounded half up like the PNG writer.
        code = floor(code * 255.0 + 0.5) / 255.0;
    }
    if (u.mode.z > 0.5) {
        return vec4<f32>(srgb_to_linear(code), 1.0);
    }
    return vec4<f32>(code, 1.0);
}
