//! Links the C++ runtime: intel_tex_2's prebuilt ISPC texture-compressor libraries contain a C++ object
//! (its ASTC helper) that references libstdc++ (libc++ on Apple), which rustc's linker does not add.

fn main() {
    let os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    let env = std::env::var("CARGO_CFG_TARGET_ENV").unwrap_or_default();
    match (os.as_str(), env.as_str()) {
        ("macos" | "ios", _) => println!("cargo:rustc-link-lib=c++"),
        ("windows", "msvc") => {}
        _ => println!("cargo:rustc-link-lib=stdc++"),
    }
    println!("cargo:rerun-if-changed=build.rs");
}
