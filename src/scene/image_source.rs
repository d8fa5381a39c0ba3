//! Lazily decoded images.
#[derive(Clone, Debug)]
pub struct ImageSource {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub has_alpha: bool,
}
/// A decoded image: RGBA8, sRGB colour, straight alpha, row-major, top row first.
#[derive(Clone, Debug)]
pub struct DecodedImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[u8; 4]>,
}
