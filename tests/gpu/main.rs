//! All GPU tests, in one `harness = false` binary that opens the device once (see `harness.rs` for the policy).
//!
//! To add tests: create a module under `tests/gpu/` with `pub fn tests() -> Vec<GpuTest>` and list it below.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test code: a failed unwrap is a failed test"
)]

mod alpha;
mod arrays;
mod compressed;
mod deep;
mod device;
mod extent;
#[path = "../fixtures/corners.rs"]
mod fixtures;
mod golden;
mod harness;
mod paging;
#[path = "../fixtures/peel_strip.rs"]
mod peel_strip;
mod planner;
mod reference;
mod render;
mod residency;
mod shader_math;
#[path = "../fixtures/shader_math.rs"]
mod shader_math_grid;
mod shared;
mod smoke;
mod sweep;
mod view;

use std::process::ExitCode;

fn main() -> ExitCode {
    let registry: Vec<harness::GpuTest> = [
        smoke::tests(),
        device::tests(),
        extent::tests(),
        deep::tests(),
        arrays::tests(),
        render::tests(),
        reference::tests(),
        golden::tests(),
        paging::tests(),
        planner::tests(),
        residency::tests(),
        view::tests(),
        sweep::tests(),
        compressed::tests(),
        alpha::tests(),
        shared::tests(),
        shader_math::tests(),
    ]
    .into_iter()
    .flatten()
    .collect();
    harness::run_main(&registry)
}
