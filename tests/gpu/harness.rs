//! The GPU-test policy: one binary, one shared [`GpuContext`], a registry of plain functions.
//!
//! - Every GPU test is a [`GpuTestFn`] registered in a module's `tests()` list and collected in `main.rs`.
//! - The context is created once. Each test runs inside a wgpu validation/out-of-memory error scope and under
//!   `catch_unwind`, so a validation error or a panic fails that test only.
//! - Output: `test <name> ... ok|FAILED|SKIPPED (no GPU adapter)` per test, then the closing line
//!   `gpu: P passed, F failed, S skipped`. Exit code 1 when any test failed.
//! - No adapter: every test is a loud skip, unless `ATLASTREE_REQUIRE_GPU=1`, where every test fails.
//! - libtest flags that cargo or tools pass are accepted and ignored; one positional argument filters by substring.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::process::ExitCode;
use std::time::Instant;

use atlastree::gpu::{GpuContext, GpuError, GpuOptions};

/// A GPU test: `Ok(())` passes, `Err(message)` fails with that message.
pub type GpuTestFn = fn(&GpuContext) -> Result<(), String>;

/// One registry entry.
pub struct GpuTest {
    /// Printed name, `module::test`.
    pub name: &'static str,
    pub run: GpuTestFn,
}

/// Environment variable that turns a missing adapter into a failure (set by `.ci/run`).
pub const REQUIRE_GPU_ENV: &str = "ATLASTREE_REQUIRE_GPU";

/// Command-line arguments understood by the harness.
#[derive(Debug, Default, PartialEq)]
struct Args {
    /// Positional substring filter.
    filter: Option<String>,
    /// `--exact`: the filter must equal the name.
    exact: bool,
    /// `--list`: print names in libtest's terse format and exit.
    list: bool,
    /// `--ignored`: run only ignored tests, of which there are none.
    ignored_only: bool,
    /// `--skip X`: names containing X are filtered out.
    skip: Vec<String>,
}

/// libtest flags that take a value (`--flag value` or `--flag=value`) and are ignored.
const IGNORED_WITH_VALUE: &[&str] = &[
    "--test-threads",
    "--format",
    "--color",
    "-Z",
    "--logfile",
    "--report-time",
];

fn parse_args(args: impl IntoIterator<Item = String>) -> Args {
    let mut parsed = Args::default();
    let mut iter = args.into_iter();
    while let Some(arg) = iter.next() {
        match arg.as_str() {
            "--exact" => parsed.exact = true,
            "--list" => parsed.list = true,
            "--ignored" => parsed.ignored_only = true,
            "--skip" => parsed.skip.extend(iter.next()),
            a if IGNORED_WITH_VALUE.contains(&a) => {
                iter.next();
            }
            a if a.starts_with('-') => {} // --nocapture, -q, --quiet, --include-ignored, --flag=value, ...
            _ => parsed.filter = Some(arg),
        }
    }
    parsed
}

fn selected(args: &Args, name: &str) -> bool {
    if args.ignored_only || args.skip.iter().any(|s| name.contains(s.as_str())) {
        return false;
    }
    match &args.filter {
        None => true,
        Some(f) if args.exact => name == f,
        Some(f) => name.contains(f.as_str()),
    }
}

#[derive(Default)]
struct Counts {
    passed: usize,
    failed: usize,
    skipped: usize,
}

/// Runs the selected tests of `registry` and returns the process exit code.
pub fn run_main(registry: &[GpuTest]) -> ExitCode {
    let args = parse_args(std::env::args().skip(1));
    let tests: Vec<&GpuTest> = registry
        .iter()
        .filter(|t| selected(&args, t.name))
        .collect();
    if args.list {
        for t in &tests {
            println!("{}: test", t.name);
        }
        return ExitCode::SUCCESS;
    }
    let filtered_out = registry.len() - tests.len();
    println!(
        "\nrunning {} GPU tests ({} filtered out)",
        tests.len(),
        filtered_out
    );
    let require = std::env::var(REQUIRE_GPU_ENV).is_ok_and(|v| v == "1");
    let mut counts = Counts::default();
    if !tests.is_empty() {
        let start = Instant::now();
        match GpuContext::new_headless(&GpuOptions::default()) {
            Ok(ctx) => {
                println!(
                    "gpu: adapter {} (context in {:.2} s)",
                    ctx.adapter_summary(),
                    start.elapsed().as_secs_f64()
                );
                println!("gpu: {}", ctx.features);
                run_all(&ctx, &tests, &mut counts);
            }
            Err(err) => report_no_adapter(&err, &tests, require, &mut counts),
        }
    }
    println!(
        "gpu: {} passed, {} failed, {} skipped",
        counts.passed, counts.failed, counts.skipped
    );
    if counts.failed > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

fn run_all(ctx: &GpuContext, tests: &[&GpuTest], counts: &mut Counts) {
    let mut failures = Vec::new();
    for t in tests {
        let start = Instant::now();
        let outcome = run_one(ctx, t);
        let secs = start.elapsed().as_secs_f64();
        match outcome {
            Ok(()) => {
                counts.passed += 1;
                println!("test {} ... ok ({secs:.2} s)", t.name);
            }
            Err(message) => {
                counts.failed += 1;
                println!("test {} ... FAILED ({secs:.2} s)", t.name);
                failures.push((t.name, message));
            }
        }
    }
    if !failures.is_empty() {
        println!("\nfailures:");
        for (name, message) in &failures {
            println!("---- {name} ----\n{message}\n");
        }
    }
}

/// One test under an error scope and `catch_unwind`.
fn run_one(ctx: &GpuContext, t: &GpuTest) -> Result<(), String> {
    let caught = catch_unwind(AssertUnwindSafe(|| ctx.scoped(t.name, |_| (t.run)(ctx))));
    match caught {
        Ok(Ok(result)) => result,
        Ok(Err(wgpu_error)) => Err(wgpu_error.to_string()),
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "non-string panic payload".to_owned());
            Err(format!("panicked: {message}"))
        }
    }
}

fn report_no_adapter(err: &GpuError, tests: &[&GpuTest], require: bool, counts: &mut Counts) {
    let n = tests.len();
    if require {
        println!(
            "==== FAILED ({REQUIRE_GPU_ENV}=1 and no GPU adapter): {n} GPU tests cannot run: {err} ===="
        );
        for t in tests {
            println!("test {} ... FAILED (no GPU adapter)", t.name);
        }
        counts.failed += n;
    } else {
        let banner = format!(
            "==== SKIPPED (no GPU adapter): {n} GPU tests did not run; install mesa-vulkan-drivers ({err}) ===="
        );
        println!("{banner}");
        eprintln!("{banner}");
        for t in tests {
            println!("test {} ... SKIPPED (no GPU adapter)", t.name);
        }
        counts.skipped += n;
    }
}

/// `ctx` as an adapter with `features` would present it (same instance, adapter, device and queue): how a
/// test sees what the renderer does on a device without BC support or with a smaller allocation limit.
pub(crate) fn with_features(
    ctx: &atlastree::gpu::GpuContext,
    features: atlastree::gpu::GpuFeatures,
) -> atlastree::gpu::GpuContext {
    atlastree::gpu::GpuContext {
        instance: ctx.instance.clone(),
        adapter: ctx.adapter.clone(),
        device: ctx.device.clone(),
        queue: ctx.queue.clone(),
        info: ctx.info.clone(),
        features,
    }
}
