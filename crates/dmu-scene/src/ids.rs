//! Dense `u32` ids, one type per kind so they cannot be mixed up.

use serde::{Deserialize, Serialize};

macro_rules! id_type {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
        #[derive(bytemuck::Pod, bytemuck::Zeroable)]
        #[repr(transparent)]
        pub struct $name(pub u32);

        impl $name {
            /// The id as an index into its scene array.
            pub const fn index(self) -> usize {
                self.0 as usize
            }

            /// The id of the element at `index`; panics past `u32::MAX`, which no scene reaches.
            pub fn from_index(index: usize) -> Self {
                Self(u32::try_from(index).expect(concat!(stringify!($name), " overflows u32")))
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "#{}", self.0)
            }
        }
    };
}

id_type!(
    /// A part: an assembly node that owns geometry (one mesh instance).
    PartId
);
id_type!(
    /// A node of the assembly tree (product structure); node 0 is the root.
    NodeId
);
id_type!(
    /// Part-local geometry, shared by every part that instances it.
    MeshId
);
id_type!(
    /// A spatially compact piece of one mesh: the unit of loading, drawing and picking.
    ChunkId
);
id_type!(
    /// A material (base colour).
    MaterialId
);
