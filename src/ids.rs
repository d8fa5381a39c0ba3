//! Newtypes for ids and coordinates, so a node index is never confused with a block, a layer or a leaf.
//!
//! All ids are dense indices into the table they name (`NodeId(3)` is `nodes[3]`). `u32::MAX` is never a
//! valid id; records on disk use [`NONE`] for "absent".

use bytemuck::{Pod, Zeroable};
use serde::{Deserialize, Serialize};

/// "Absent" in on-disk records (`u32::MAX`).
pub const NONE: u32 = u32::MAX;

macro_rules! id_type {
    ($(#[$m:meta])* $name:ident) => {
        $(#[$m])*
        #[derive(Copy, Clone, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Pod, Zeroable, Serialize, Deserialize)]
        #[repr(transparent)]
        pub struct $name(pub u32);

        impl $name {
            /// The index into the table this id names.
            #[inline]
            pub fn idx(self) -> usize {
                self.0 as usize
            }
            /// `None` for the on-disk sentinel [`NONE`].
            #[inline]
            pub fn from_raw(raw: u32) -> Option<Self> {
                (raw != NONE).then_some(Self(raw))
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{}#{}", stringify!($name), self.0)
            }
        }
    };
}

id_type!(
    /// A node of an atlas tree (index into the node table; the root is `NodeId(0)`).
    NodeId
);
id_type!(
    /// A leaf of an atlas tree (index into the leaf table; leaves are numbered in tree order).
    LeafId
);
id_type!(
    /// A texture block of the paging file (an atlas, or a part of a leaf's original textures).
    BlockId
);
id_type!(
    /// A layer of a GPU texture array (a paging slot).
    Layer
);
id_type!(
    /// An image of the imported scene.
    ImageId
);
id_type!(
    /// A material of the imported scene.
    MaterialId
);

/// Depth in the tree: the root is level 0, its children level 1, and so on.
#[derive(
    Copy, Clone, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Level(pub u8);

/// Integer cell of a node at its level: the node's atlas is the square `[ix, ix+1) × [iy, iy+1)` of the
/// root atlas scaled by `2^level` (paper §5.1, Fig. 4). `ix, iy < 2^level`.
#[derive(
    Copy, Clone, Debug, Default, PartialEq, Eq, Hash, Pod, Zeroable, Serialize, Deserialize,
)]
#[repr(C)]
pub struct Cell {
    pub ix: u32,
    pub iy: u32,
}

impl Cell {
    /// The cell of child `quadrant` (0..4: bit 0 = +x half, bit 1 = +y half of the parent's atlas).
    #[inline]
    pub fn child(self, quadrant: u32) -> Cell {
        Cell {
            ix: self.ix * 2 + (quadrant & 1),
            iy: self.iy * 2 + (quadrant >> 1),
        }
    }
}
