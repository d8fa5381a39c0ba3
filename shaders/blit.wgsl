// The viewer's present pass (src/view/present.rs): copies the composited frame (the renderer's image with
// the egui overlay on top) texel for texel into the window's surface texture.
//
// One full-screen triangle; each fragment loads the texel under it (no filtering, so equal sizes copy
// exactly; a larger target repeats the last row/column). Both sides are bound as non-sRGB views, so the
// stored sRGB-encoded bytes pass through unchanged; a BGRA surface is swizzled by the hardware on write.

@group(0) @binding(0) var source: texture_2d<f32>;

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
    let size = textureDimensions(source);
    let texel = min(vec2<u32>(in.clip.xy), size - vec2<u32>(1u, 1u));
    return textureLoad(source, texel, 0);
}
