//! All GPU tests, in one `harness = false` binary that opens the device once (see `harness.rs` for the policy).
//!
//! To add tests: create a module under `tests/gpu/` with `pub fn tests() -> Vec<GpuTest>` and list it below.

mod alpha;
mod compressed;
mod device;
mod extent;
#[path = "../fixtures/corners.rs"]
mod fixtures;
mod golden;
mod harness;
mod paging;
mod planner;
mod render;
mod residency;
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
        render::tests(),
        golden::tests(),
        paging::tests(),
        planner::tests(),
        residency::tests(),
        view::tests(),
        sweep::tests(),
        compressed::tests(),
        alpha::tests(),
        shared::tests(),
    ]
    .into_iter()
    .flatten()
    .collect();
    harness::run_main(&registry)
}
