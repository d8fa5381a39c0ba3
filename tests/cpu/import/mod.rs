//! `scene::import`: glTF 2.0 in, a flat scene out.

mod accessors;
mod bad_input;
mod budget;
mod city;
mod extensions;
mod features;
mod khronos;
mod synthetic;
mod tiled;
