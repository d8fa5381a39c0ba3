//! Accessor reading: glTF accessors (buffer bytes) → f64 components or u32 indices, every byte range
//! checked.
//!
//! Input: the loaded buffers (`&[Option<Vec<u8>>]`, indexed by glTF buffer; see
//! [`super::uri::Buffers`]) and a [`gltf::Accessor`]. Output: `count × dims` f64 values in element
//! order, with sparse substitution applied and normalised integers mapped to [0, 1] / [-1, 1] as the
//! glTF specification says, or u32 vertex indices. A view, stride or sparse range past its buffer is an
//! [`AccErr`] naming the accessor; [`PrimCtx::error`] attaches the mesh and primitive to make it a
//! [`SceneError`].

use crate::scene::error::SceneError;
use gltf::accessor::{DataType, Dimensions};

/// Cap on accessors without a buffer view (sparse-only, zero-initialised), in elements: such an accessor
/// costs no bytes in the file, so its count alone must not decide the allocation (2^24 VEC3 elements
/// are 384 MiB of f64).
const MAX_SPARSE_ONLY_COUNT: usize = 1 << 24;

/// Mesh/primitive identification for errors and warnings.
pub(super) struct PrimCtx {
    pub(super) mesh: usize,
    pub(super) mesh_name: String,
    pub(super) primitive: usize,
}

/// An accessor-level failure before the mesh context is attached.
pub(super) struct AccErr {
    pub(super) accessor: usize,
    pub(super) reason: String,
}

impl PrimCtx {
    /// `e` as a [`SceneError::Accessor`] of this primitive in `file`, read as `semantic`.
    pub(super) fn error(&self, file: &str, semantic: &str, e: AccErr) -> SceneError {
        SceneError::Accessor {
            file: file.to_string(),
            mesh: self.mesh,
            mesh_name: self.mesh_name.clone(),
            primitive: self.primitive,
            accessor: e.accessor,
            reason: format!("{semantic}: {}", e.reason),
        }
    }
}

fn component_size(t: DataType) -> usize {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

fn dimension_count(d: Dimensions) -> usize {
    match d {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 | Dimensions::Mat2 => 4,
        Dimensions::Mat3 => 9,
        Dimensions::Mat4 => 16,
    }
}

/// One component as f64 (`b` holds exactly `component_size(t)` bytes). Normalised integers map to
/// [0, 1] (unsigned) or [-1, 1] (signed, `max(v / MAX, -1)`), per the glTF specification.
#[inline]
fn decode_component(t: DataType, normalized: bool, b: &[u8]) -> f64 {
    let (v, max) = match t {
        DataType::F32 => return f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        DataType::I8 => (f64::from(b[0] as i8), 127.0),
        DataType::U8 => (f64::from(b[0]), 255.0),
        DataType::I16 => (f64::from(i16::from_le_bytes([b[0], b[1]])), 32767.0),
        DataType::U16 => (f64::from(u16::from_le_bytes([b[0], b[1]])), 65535.0),
        DataType::U32 => (
            f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            4_294_967_295.0,
        ),
    };
    if normalized { (v / max).max(-1.0) } else { v }
}

/// The bytes of buffer view `view`, checked against the loaded buffer.
pub(super) fn view_slice<'b>(
    buffers: &'b [Option<Vec<u8>>],
    view: &gltf::buffer::View,
) -> Result<&'b [u8], String> {
    let b = view.buffer().index();
    let buf = buffers
        .get(b)
        .and_then(|x| x.as_deref())
        .ok_or_else(|| format!("buffer {b} not loaded"))?;
    let end = view
        .offset()
        .checked_add(view.length())
        .ok_or("buffer view range overflows")?;
    buf.get(view.offset()..end).ok_or_else(|| {
        format!(
            "buffer view {} (bytes {}..{end}) exceeds buffer {b} of {} bytes",
            view.index(),
            view.offset(),
            buf.len()
        )
    })
}

/// Dense element layout inside a view: `count` elements of `elem` bytes, `stride` apart, from `offset`.
struct Dense<'b> {
    data: &'b [u8],
    stride: usize,
    elem: usize,
    count: usize,
}

fn dense<'b>(
    buffers: &'b [Option<Vec<u8>>],
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    elem: usize,
    use_view_stride: bool,
) -> Result<Dense<'b>, String> {
    let vs = view_slice(buffers, view)?;
    let stride = if use_view_stride {
        view.stride().unwrap_or(elem)
    } else {
        elem
    };
    if stride < elem {
        return Err(format!(
            "byteStride {stride} is smaller than the element size {elem}"
        ));
    }
    if count == 0 {
        return Ok(Dense {
            data: &[],
            stride,
            elem,
            count,
        });
    }
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(offset))
        .and_then(|x| x.checked_add(elem))
        .ok_or("accessor byte range overflows")?;
    let data = vs.get(offset..end).ok_or_else(|| {
        format!(
            "{count} elements of {elem} bytes (stride {stride}) from byte {offset} end at byte {end}, past the end \
             of buffer view {} ({} bytes)",
            view.index(),
            vs.len()
        )
    })?;
    Ok(Dense {
        data,
        stride,
        elem,
        count,
    })
}

impl Dense<'_> {
    /// The element slices (each exactly `elem` bytes).
    fn elements(&self) -> impl Iterator<Item = &[u8]> {
        self.elements_from(0)
    }

    /// The element slices from element `start` on (none where `start ≥ count`), found by offset, not by
    /// walking the elements before it.
    fn elements_from(&self, start: usize) -> impl Iterator<Item = &[u8]> {
        let rest = start
            .checked_mul(self.stride)
            .and_then(|at| self.data.get(at..))
            .unwrap_or_default();
        rest.chunks(self.stride)
            .take(self.count.saturating_sub(start))
            .filter_map(|c| c.get(..self.elem))
    }
}

/// Refuses an `UNSIGNED_INT` vertex attribute: glTF allows FLOAT positions and texture coordinates, and
/// with `KHR_mesh_quantization` 8- and 16-bit integers, never 32-bit ones (read as integers, float bits
/// made a 10 m quad a billion metres wide, silently).
pub(super) fn check_vertex_attribute(acc: &gltf::Accessor) -> Result<(), AccErr> {
    if acc.data_type() == DataType::U32 {
        return Err(AccErr {
            accessor: acc.index(),
            reason: "is UNSIGNED_INT (5125): vertex attributes are FLOAT, or 8- or 16-bit integers with \
                     KHR_mesh_quantization"
                .into(),
        });
    }
    Ok(())
}

/// Reads accessor `acc` as `count × dims` f64 into `out` (sparse substitution applied). The accessor
/// must have exactly `dims` components per element.
pub(super) fn read_floats(
    buffers: &[Option<Vec<u8>>],
    acc: &gltf::Accessor,
    dims: usize,
    out: &mut Vec<f64>,
    tmp: &mut Vec<f64>,
) -> Result<(), AccErr> {
    read_float_range(buffers, acc, dims, 0..acc.count(), out, tmp)
}

/// [`read_floats`] for the elements in `range` alone (`range.len() × dims` values in `out`): the whole
/// accessor is checked as [`read_floats`] checks it (view bounds, sparse indices), but only the
/// elements in `range` are decoded, so primitives that share one large vertex accessor each read the
/// part their indices use (a three.js exporter's geometry groups: 10,000 primitives over one accessor
/// took 6.6 s to import, each reading all of it; fault hunt, session 36). `range` must lie inside the
/// accessor's count.
pub(super) fn read_float_range(
    buffers: &[Option<Vec<u8>>],
    acc: &gltf::Accessor,
    dims: usize,
    range: std::ops::Range<usize>,
    out: &mut Vec<f64>,
    tmp: &mut Vec<f64>,
) -> Result<(), AccErr> {
    let err = |reason: String| AccErr {
        accessor: acc.index(),
        reason,
    };
    let got = dimension_count(acc.dimensions());
    if got != dims {
        return Err(err(format!(
            "has {:?} elements, expected {dims} components",
            acc.dimensions()
        )));
    }
    let t = acc.data_type();
    let cs = component_size(t);
    let norm = acc.normalized();
    let count = acc.count();
    if range.end > count || range.start > range.end {
        return Err(err(format!(
            "internal: elements {}..{} read from {count}",
            range.start, range.end
        )));
    }
    let wanted = range.len();
    out.clear();
    match acc.view() {
        Some(view) => {
            let d = dense(buffers, &view, acc.offset(), count, cs * dims, true).map_err(err)?;
            out.reserve(wanted * dims);
            for e in d.elements_from(range.start).take(wanted) {
                out.extend(e.chunks_exact(cs).map(|b| decode_component(t, norm, b)));
            }
        }
        None => {
            if count > MAX_SPARSE_ONLY_COUNT {
                return Err(err(format!("{count} elements without a buffer view")));
            }
            out.resize(wanted * dims, 0.0);
        }
    }
    if out.len() != wanted * dims {
        return Err(err("short read".into()));
    }
    if let Some(sp) = acc.sparse() {
        let mut idx = Vec::new();
        let iv = sp.indices();
        let it = match iv.index_type() {
            gltf::accessor::sparse::IndexType::U8 => DataType::U8,
            gltf::accessor::sparse::IndexType::U16 => DataType::U16,
            gltf::accessor::sparse::IndexType::U32 => DataType::U32,
        };
        let n = sp.count();
        if n > count {
            return Err(err(format!(
                "sparse count {n} exceeds the accessor's {count} elements"
            )));
        }
        let d = dense(
            buffers,
            &iv.view(),
            iv.offset(),
            n,
            component_size(it),
            false,
        )
        .map_err(|r| err(format!("sparse indices: {r}")))?;
        idx.extend(
            d.elements()
                .map(|b| decode_component(it, false, b) as usize),
        );
        let vv = sp.values();
        let values = dense(buffers, &vv.view(), vv.offset(), n, cs * dims, false)
            .map_err(|r| err(format!("sparse values: {r}")))?;
        // glTF 2.0 §3.6.2.3: sparse indices MUST strictly increase (a repeated index would make the
        // element depend on which write comes last).
        if let Some(k) = idx.windows(2).position(|w| w[1] <= w[0]) {
            return Err(err(format!(
                "sparse indices must strictly increase: index {k} is {}, index {} is {}",
                idx[k],
                k + 1,
                idx[k + 1]
            )));
        }
        if let Some(&i) = idx.iter().find(|&&i| i >= count) {
            return Err(err(format!(
                "sparse index {i} out of range ({count} elements)"
            )));
        }
        // Only the values inside `range` are decoded (the indices increase, so they are one run of
        // them): primitives sharing one sparse accessor each decoded all its values.
        let first = idx.partition_point(|&i| i < range.start);
        let inside = idx[first..].partition_point(|&i| i < range.end);
        for (k, e) in (first..first + inside).zip(values.elements_from(first)) {
            let i = idx[k];
            let dst = (i - range.start)
                .checked_mul(dims)
                .and_then(|s| out.get_mut(s..s + dims))
                .ok_or_else(|| err(format!("sparse index {i} out of range ({count} elements)")))?;
            tmp.clear();
            tmp.extend(e.chunks_exact(cs).map(|b| decode_component(t, norm, b)));
            if tmp.len() != dims {
                return Err(err("sparse values short".into()));
            }
            dst.copy_from_slice(tmp);
        }
    }
    Ok(())
}

/// Reads an index accessor (SCALAR of u8/u16/u32) into `out`.
pub(super) fn read_indices(
    buffers: &[Option<Vec<u8>>],
    acc: &gltf::Accessor,
    out: &mut Vec<u32>,
    tmp: &mut Vec<f64>,
) -> Result<(), AccErr> {
    let err = |reason: String| AccErr {
        accessor: acc.index(),
        reason,
    };
    let t = acc.data_type();
    if acc.dimensions() != Dimensions::Scalar
        || !matches!(t, DataType::U8 | DataType::U16 | DataType::U32)
    {
        return Err(err(format!(
            "indices must be SCALAR of unsigned byte/short/int, found {:?} of {t:?}",
            acc.dimensions()
        )));
    }
    out.clear();
    if acc.sparse().is_some() || acc.view().is_none() {
        let mut vals = Vec::new();
        read_floats(buffers, acc, 1, &mut vals, tmp)?;
        out.extend(vals.iter().map(|&v| v as u32));
        return Ok(());
    }
    let Some(view) = acc.view() else {
        return Ok(());
    };
    let cs = component_size(t);
    let d = dense(buffers, &view, acc.offset(), acc.count(), cs, true).map_err(err)?;
    out.reserve(acc.count());
    match t {
        DataType::U8 => out.extend(d.elements().map(|b| u32::from(b[0]))),
        DataType::U16 => out.extend(
            d.elements()
                .map(|b| u32::from(u16::from_le_bytes([b[0], b[1]]))),
        ),
        _ => out.extend(
            d.elements()
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        ),
    }
    Ok(())
}

/// An accessor's count if its dense range fits its view's declared length, else 0 (used for
/// reservations only; the real check happens when reading).
pub(super) fn plausible_count(acc: &gltf::Accessor) -> usize {
    let Some(view) = acc.view() else { return 0 };
    let elem = component_size(acc.data_type()) * dimension_count(acc.dimensions());
    let stride = view.stride().unwrap_or(elem).max(elem);
    let fits = acc
        .count()
        .checked_sub(1)
        .and_then(|c| c.checked_mul(stride))
        .and_then(|x| x.checked_add(acc.offset()))
        .and_then(|x| x.checked_add(elem))
        .is_some_and(|end| end <= view.length());
    if fits { acc.count() } else { 0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalized_components() {
        assert_eq!(decode_component(DataType::U8, true, &[255]), 1.0);
        assert_eq!(decode_component(DataType::I8, true, &[0x80]), -1.0);
        assert_eq!(decode_component(DataType::U16, true, &[0xff, 0xff]), 1.0);
        assert_eq!(decode_component(DataType::U16, false, &[2, 1]), 258.0);
    }
}
