//! The GPU residency of blocks (`render::resident`) under broken inputs, on data/city's deep tree: every
//! failure is an error that leaves the bookkeeping as it was, never a wrong texture.
//!
//! - an originals block whose bytes are short is refused and holds no reference and no layer; loaded
//!   intact afterwards it gets a layer per texture, evicted it frees them, and evicting it again is an
//!   error (a reference count that is already 0), not a silent no-op;
//! - class arrays sized for one block refuse the textures of a second block with an error, and count no
//!   reference for them (the count was raised before the layer was allocated: after the failure it held a
//!   reference without a layer, and a later eviction freed a layer another texture used);
//! - atlas arrays sized for one layer refuse a second atlas with an error instead of writing over layer 0.

use atlastree::gpu::GpuContext;
use atlastree::ids::BlockId;
use atlastree::paging::{BlockTable, Event};
use atlastree::render::RenderError;
use atlastree::render::resident::Resident;
use atlastree::store::TreeFile;

use crate::harness::GpuTest;
use crate::render::{city_deep, e};

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "residency::a_short_originals_block_changes_no_reference",
            run: a_short_originals_block_changes_no_reference,
        },
        GpuTest {
            name: "residency::a_full_class_array_refuses_and_counts_no_reference",
            run: a_full_class_array_refuses_and_counts_no_reference,
        },
        GpuTest {
            name: "residency::a_full_atlas_array_refuses_instead_of_overwriting",
            run: a_full_atlas_array_refuses_instead_of_overwriting,
        },
    ]
}

fn loaded(block: BlockId, bytes: &[u8]) -> Event {
    Event::Loaded {
        block,
        data: Some(bytes.to_vec()),
    }
}

fn a_short_originals_block_changes_no_reference(ctx: &GpuContext) -> Result<(), String> {
    let path = city_deep()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let table = BlockTable::from_file(&file).map_err(e)?;
    let all = table.len() as u32;
    let mut r = Resident::load_paged(ctx, &file, &table, all).map_err(e)?;
    // The originals block holding the most textures.
    let block = (0..all)
        .map(BlockId)
        .filter(|&b| !table.meta(b).item.is_atlas())
        .max_by_key(|b| r.residency.block_uniques[b.idx()].len())
        .ok_or("no originals block")?;
    let textures = r.residency.block_uniques[block.idx()].len() as u32;
    if textures < 2 {
        return Err(format!(
            "{block} holds {textures} texture(s): the test proves little"
        ));
    }
    let bytes = file.block(block).map_err(e)?.to_vec();
    // Cut inside the last texture's chain: the first ones alone would upload.
    let short = &bytes[..bytes.len() - 16];
    match r.apply(&ctx.queue, &loaded(block, short)) {
        Err(RenderError::ShortBlock { block: b }) if b == block => {}
        other => return Err(format!("a short block gave {other:?}")),
    }
    let refs: u32 = r.residency.unique_refs.iter().sum();
    if refs != 0 || r.residency.original_layers_used != 0 {
        return Err(format!(
            "after the refused upload: {refs} references, {} layers in use",
            r.residency.original_layers_used
        ));
    }
    r.apply(&ctx.queue, &loaded(block, &bytes)).map_err(e)?;
    if r.residency.original_layers_used != textures {
        return Err(format!(
            "{} layers in use for the {textures} textures of {block}",
            r.residency.original_layers_used
        ));
    }
    // Every texture of the block has its own allocated layer in a binding of its class.
    let mut places = std::collections::BTreeSet::new();
    for &(u, _) in &r.residency.block_uniques[block.idx()] {
        let un = &r.uniques[u as usize];
        places.insert((un.slot, un.layer));
        if r.residency.slot_class[un.slot as usize] != Some(un.class) {
            return Err(format!(
                "unique {u} of class {} sits in binding {} of class {:?}",
                un.class, un.slot, r.residency.slot_class[un.slot as usize]
            ));
        }
    }
    if places.len() as u32 != textures {
        return Err(format!("{textures} textures share {} layers", places.len()));
    }
    r.apply(&ctx.queue, &Event::Evicted { block }).map_err(e)?;
    if r.residency.original_layers_used != 0 {
        return Err(format!(
            "{} layers still in use after the eviction",
            r.residency.original_layers_used
        ));
    }
    match r.apply(&ctx.queue, &Event::Evicted { block }) {
        Err(RenderError::Residency { .. }) => Ok(()),
        other => Err(format!("evicting a block twice gave {other:?}")),
    }
}

fn a_full_atlas_array_refuses_instead_of_overwriting(ctx: &GpuContext) -> Result<(), String> {
    let path = city_deep()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let table = BlockTable::from_file(&file).map_err(e)?;
    let mut r = Resident::load_paged(ctx, &file, &table, 1).map_err(e)?;
    let atlases: Vec<BlockId> = (0..table.len() as u32)
        .map(BlockId)
        .filter(|&b| table.meta(b).item.is_atlas() && table.meta(b).tree == 0)
        .take(2)
        .collect();
    let [first, second] = atlases[..] else {
        return Err("fewer than two atlases in tree 0".into());
    };
    let bytes = |b: BlockId| file.block(b).map(std::borrow::Cow::into_owned).map_err(e);
    r.apply(&ctx.queue, &loaded(first, &bytes(first)?))
        .map_err(e)?;
    let node_of = |b: BlockId| table.meta(b).item.node().idx();
    let slot = r.infos[0].atlas_slots[node_of(first)];
    match r.apply(&ctx.queue, &loaded(second, &bytes(second)?)) {
        Err(RenderError::TooManyLayers { .. }) => {}
        other => {
            return Err(format!(
                "a second atlas in a one-layer array gave {other:?}"
            ));
        }
    }
    if r.infos[0].atlas_slots[node_of(second)].is_some() {
        return Err("the refused atlas got a slot".into());
    }
    if r.infos[0].atlas_slots[node_of(first)] != slot || slot.is_none() {
        return Err(format!(
            "the first atlas's slot changed: {slot:?} → {:?}",
            r.infos[0].atlas_slots[node_of(first)]
        ));
    }
    Ok(())
}

fn a_full_class_array_refuses_and_counts_no_reference(ctx: &GpuContext) -> Result<(), String> {
    let path = city_deep()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let table = BlockTable::from_file(&file).map_err(e)?;
    let mut r = Resident::load_paged(ctx, &file, &table, 1).map_err(e)?;
    let blocks: Vec<BlockId> = (0..table.len() as u32)
        .map(BlockId)
        .filter(|&b| !table.meta(b).item.is_atlas())
        .collect();
    overfill_a_class(ctx, &file, &mut r, &blocks)
}

/// Two originals blocks with distinct textures that together need more layers of some class than the
/// arrays (sized for one block) hold: the first loads, the second is refused.
fn overfill_a_class(
    ctx: &GpuContext,
    file: &TreeFile,
    r: &mut Resident,
    blocks: &[BlockId],
) -> Result<(), String> {
    for &a in blocks {
        for &b in blocks {
            if a == b {
                continue;
            }
            let ua: Vec<u32> = r.residency.block_uniques[a.idx()]
                .iter()
                .map(|x| x.0)
                .collect();
            let ub: Vec<u32> = r.residency.block_uniques[b.idx()]
                .iter()
                .map(|x| x.0)
                .collect();
            if ua.iter().any(|u| ub.contains(u)) {
                continue;
            }
            // Layers of each class the two blocks need together, against the class's capacity.
            let mut need = std::collections::BTreeMap::<u32, u32>::new();
            for &u in ua.iter().chain(&ub) {
                *need.entry(r.uniques[u as usize].class).or_default() += 1;
            }
            let over = need.iter().any(|(&c, &n)| {
                let cap: u32 = r
                    .class_arrays
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| r.residency.slot_class[*i] == Some(c))
                    .filter_map(|(_, a)| a.as_ref().map(|a| a.layers.capacity()))
                    .sum();
                n > cap
            });
            if over {
                return check_second_refused(ctx, file, r, a, b);
            }
        }
    }
    Err("no two originals blocks overfill a class at capacity 1: the test proves nothing".into())
}

fn check_second_refused(
    ctx: &GpuContext,
    file: &TreeFile,
    r: &mut Resident,
    a: BlockId,
    b: BlockId,
) -> Result<(), String> {
    let bytes = |x: BlockId| file.block(x).map(std::borrow::Cow::into_owned).map_err(e);
    r.apply(&ctx.queue, &loaded(a, &bytes(a)?)).map_err(e)?;
    let used = r.residency.original_layers_used;
    let refs_before: Vec<u32> = r.residency.unique_refs.clone();
    match r.apply(&ctx.queue, &loaded(b, &bytes(b)?)) {
        Err(RenderError::TooManyLayers { .. }) => {}
        other => return Err(format!("{b} after {a} at capacity 1 gave {other:?}")),
    }
    if r.residency.unique_refs != refs_before || r.residency.original_layers_used != used {
        return Err(format!(
            "the refused {b} changed the bookkeeping: {} → {} layers, references {:?} → {:?}",
            used,
            r.residency.original_layers_used,
            refs_before.iter().sum::<u32>(),
            r.residency.unique_refs.iter().sum::<u32>()
        ));
    }
    // The first block still evicts cleanly: its layers are its own.
    r.apply(&ctx.queue, &Event::Evicted { block: a })
        .map_err(e)?;
    if r.residency.original_layers_used != 0 {
        return Err(format!(
            "{} layers in use after evicting the only resident block",
            r.residency.original_layers_used
        ));
    }
    Ok(())
}
