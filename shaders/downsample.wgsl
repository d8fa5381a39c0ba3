// The supersampled reference's downsample (`render --reference supersampled[:S]`, render::reference): each
// output pixel is the mean of the S × S block of the S-times-larger frame above it, in linear light. The
// source is bound through an sRGB view, so `textureLoad` returns linear values; the target is sRGB, so the
// hardware encodes the mean. One full-screen triangle.
//
// Rust twins (the Params struct, bindings): render::wgsl::downsample; the CPU twin of the filter is
// report::supersample::box_downsample_linear.

struct Params {
    // S: source texels per output pixel along each axis.
    factor: u32,
    _p0: u32,
    _p1: u32,
    _p2: u32,
}

@group(0) @binding(0) var source: texture_2d<f32>;
@group(0) @binding(1) var<uniform> params: Params;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> VertexOut {
    // (-1,-1), (3,-1), (-1,3): covers the viewport.
    let x = f32(i32(i & 1u) * 4 - 1);
    let y = f32(i32(i >> 1u) * 4 - 1);
    var out: VertexOut;
    out.clip = vec4<f32>(x, y, 0.0, 1.0);
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let s = params.factor;
    let base = vec2<u32>(in.clip.xy) * s;
    var sum = vec4<f32>(0.0);
    for (var y = 0u; y < s; y++) {
        for (var x = 0u; x < s; x++) {
            sum += textureLoad(source, base + vec2<u32>(x, y), 0);
        }
    }
    return sum / f32(s * s);
}
