//! `scene::import`: glTF 2.0 in, a flat scene out.

mod bad_input;
mod extensions;
mod khronos;
mod synthetic;
mod tiled;
