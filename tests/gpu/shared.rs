//! Shared original-texture blocks on the GPU (issue 17): a corrupt shared block is refused on load
//! (counted), the leaves that need it are drawn with their ancestor atlas, and nothing goes missing.

use atlastree::camera::Camera;
use atlastree::gpu::GpuContext;
use atlastree::paging::{FileSource, UploadBudget};
use atlastree::preprocess::{NoProgress, build};
use atlastree::render::Mode;
use atlastree::store::TreeFile;
use glam::DVec3;
use std::sync::Arc;

use crate::fixtures::{POSTER, corners, options};
use crate::harness::GpuTest;
use crate::paging::{coverage_mismatch, paged};
use crate::render::{H, W, e, scale_for};

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "shared::a_corrupt_shared_block_falls_back_to_the_ancestor_atlas",
            run: a_corrupt_shared_block_falls_back_to_the_ancestor_atlas,
        },
        GpuTest {
            name: "shared::materials_sharing_a_stored_original_share_its_layer_and_draw_as_unshared",
            run: materials_sharing_a_stored_original_share_its_layer_and_draw_as_unshared,
        },
    ]
}

/// Materials that share a stored original (one image, one sampler; other factors) load it as one GPU
/// layer (keyed by material, 64 materials on one image held 64 layers and uploaded it 64 times: fault
/// hunt, session 34), while the naive baseline still binds each material's factor: the tree and
/// original frames of the shared scene are byte for byte those of the same scene with a copy of the
/// image per material, which nothing can share.
fn materials_sharing_a_stored_original_share_its_layer_and_draw_as_unshared(
    ctx: &GpuContext,
) -> Result<(), String> {
    use atlastree::paging::BlockTable;
    use atlastree::render::resident::Resident;
    let dir = tempfile::tempdir().map_err(e)?;
    let mut files = Vec::new();
    for shared in [true, false] {
        let path = dir.path().join(format!("shared-{shared}.atlastree"));
        build(
            &crate::fixtures::shared_images(shared),
            &options(),
            &path,
            &NoProgress,
        )
        .map_err(e)?;
        files.push(TreeFile::open(&path).map_err(e)?);
    }
    // Layers: one per stored (block, slot); bind groups of the naive baseline: one per material.
    let mut layers = Vec::new();
    for file in &files {
        let table = BlockTable::from_file(file).map_err(e)?;
        let r = Resident::load_paged(ctx, file, &table, table.len() as u32).map_err(e)?;
        let slots: std::collections::BTreeSet<(u32, u32)> = (0..file.trees())
            .filter_map(|t| file.tree(t))
            .flat_map(|t| t.originals.iter().map(|o| (o.block, o.slot)))
            .collect();
        if r.uniques.len() != slots.len() || r.material_originals.len() != 6 {
            return Err(format!(
                "{} layers for {} stored originals, {} material bindings for 6 materials",
                r.uniques.len(),
                slots.len(),
                r.material_originals.len()
            ));
        }
        layers.push(r.uniques.len());
    }
    if layers != [4, 6] {
        return Err(format!("layers shared / unshared {layers:?}, want [4, 6]"));
    }
    // Near the row of quads, looking along it: leaves draw their originals.
    let cams = [
        (DVec3::new(40.0, 6.0, -12.0), DVec3::new(80.0, 0.0, 10.0)),
        (DVec3::new(310.0, 4.0, 290.0), DVec3::new(320.0, 0.0, 310.0)),
        (DVec3::new(80.0, 120.0, -60.0), DVec3::new(80.0, 0.0, 10.0)),
    ];
    for (eye, target) in cams {
        let cam = Camera {
            eye,
            target,
            up: DVec3::Y,
            fov_x_deg: 60.0,
            aspect: f64::from(W) / f64::from(H),
            near: 0.5,
            far: 5000.0,
        };
        for mode in [Mode::Tree, Mode::Original] {
            let mut frames = Vec::new();
            for file in &files {
                let mut r = crate::render::renderer(ctx, file)?;
                frames.push(crate::render::frame(&mut r, file, &cam, mode)?.1);
            }
            if frames[0] != frames[1] {
                let differ = frames[0]
                    .iter()
                    .zip(&frames[1])
                    .filter(|(a, b)| a != b)
                    .count();
                return Err(format!(
                    "{mode:?} from {eye}: {differ} bytes differ between the shared and unshared scenes"
                ));
            }
        }
    }
    Ok(())
}

/// The same view paged from an intact file and from a copy whose shared poster block has one flipped
/// byte: the corrupt load is counted as a failure, the corrupt run draws part of the frame coarser
/// (the poster's leaves fall back to an ancestor atlas) while the intact run converges to none, and both
/// cover exactly the same pixels (no hole).
fn a_corrupt_shared_block_falls_back_to_the_ancestor_atlas(ctx: &GpuContext) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let good = dir.path().join("corners.atlastree");
    build(&corners(), &options(), &good, &NoProgress).map_err(e)?;
    let intact = TreeFile::open(&good).map_err(e)?;
    let t = intact.tree(0).ok_or("no tree 0")?;
    let shared = t
        .originals
        .iter()
        .find(|o| o.material == POSTER)
        .map(|o| o.block)
        .ok_or("no poster original")?;
    let users = t.originals.iter().filter(|o| o.block == shared).count();
    if users < 2 {
        return Err(format!(
            "the poster block is referenced {users} times, want ≥ 2"
        ));
    }
    let rec = intact.blocks()[shared as usize];
    let mut bytes = std::fs::read(&good).map_err(e)?;
    bytes[rec.offset as usize + 100] ^= 0xff;
    let bad = dir.path().join("corrupt.atlastree");
    std::fs::write(&bad, &bytes).map_err(e)?;
    let corrupt = TreeFile::open(&bad).map_err(e)?;
    // 1.5 m above the south-east poster (its leaf's min_distance is ~2.4 m at 320 px): the leaf draws
    // its originals, the poster among them.
    let cam = Camera {
        eye: DVec3::new(350.0, 1.5, 344.0),
        target: DVec3::new(350.0, 0.0, 356.0),
        up: DVec3::Y,
        fov_x_deg: 60.0,
        aspect: f64::from(W) / f64::from(H),
        near: 0.5,
        far: 5000.0,
    };
    let k = intact.blocks().len() as u32;
    let run = |file: &TreeFile| -> Result<(u32, f64, Vec<u8>), String> {
        let source = Arc::new(FileSource::new(Arc::new(
            TreeFile::open(file.path()).map_err(e)?,
        )));
        let mut r = paged(ctx, file, k, UploadBudget::Unlimited, source, 0)?;
        let scale = scale_for(file, &cam)?;
        let (mut failures, mut coarse) = (0, 0.0);
        for _ in 0..30 {
            let s = r.render(&cam, scale, Mode::Tree).map_err(e)?;
            let p = s.plan.paging.ok_or("not paged")?;
            failures += p.session.pager.failures;
            coarse = p.coarse.share();
        }
        Ok((failures, coarse, r.read_frame().map_err(e)?))
    };
    let (good_failures, good_coarse, good_frame) = run(&intact)?;
    let (bad_failures, bad_coarse, bad_frame) = run(&corrupt)?;
    println!(
        "  intact: {good_failures} failed loads, coarser share {good_coarse:.3}; corrupt shared block: \
         {bad_failures} failed loads, coarser share {bad_coarse:.3}"
    );
    if good_failures != 0 || good_coarse != 0.0 {
        return Err(format!(
            "intact file: {good_failures} failures, coarser {good_coarse}"
        ));
    }
    if bad_failures == 0 || bad_coarse <= 0.0 {
        return Err(format!(
            "corrupt shared block: {bad_failures} failures counted, coarser share {bad_coarse} (want > 0)"
        ));
    }
    let holes = coverage_mismatch(&good_frame, &bad_frame);
    if holes != 0 {
        return Err(format!("{holes} pixels differ in coverage: a hole"));
    }
    Ok(())
}
