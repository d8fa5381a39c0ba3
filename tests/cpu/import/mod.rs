//! `scene::import`: glTF 2.0 in, a flat scene out.

mod khronos;
mod synthetic;
mod tiled;
