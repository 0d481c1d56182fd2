//! The skeleton as a TreeQSM-style cylinder table (CSV), which forestry
//! tools that read quantitative structure models already understand.
//!
//! One row per internode: the cylinder runs from the parent node to the
//! child node, with the child node's radius (each non-root node owns the
//! internode that ends at it, as in [`super::lod`]). `id` is the child node's
//! index, so ids start at 1 and `parent` is the id of the cylinder below, or
//! 0 for cylinders starting at the root, as in TreeQSM's 1-based tables.
//! `branch_order` is 0 on the trunk and grows by one at each lateral.

use std::fmt::Write;

use crate::skeleton::Skeleton;

/// The CSV header line of [`cylinder_table_csv`].
pub const CYLINDER_TABLE_HEADER: &str = "id,parent,branch_order,start_x,start_y,start_z,\
axis_x,axis_y,axis_z,length_m,radius_m";

/// Encodes the skeleton as a cylinder table: start in absolute CRS
/// coordinates, unit axis, length and radius in metres, parent id, branch
/// order.
pub fn cylinder_table_csv(skeleton: &Skeleton) -> String {
    let orders = skeleton.branch_orders();
    let mut out = String::with_capacity(skeleton.len() * 96);
    out.push_str(CYLINDER_TABLE_HEADER);
    out.push('\n');
    for (parent, child) in skeleton.internodes() {
        let start = skeleton.absolute_position(parent);
        let vector = skeleton.position(child) - skeleton.position(parent);
        let length = vector.length();
        // A zero-length internode has no direction; write a zero axis, not NaN.
        let axis = vector.try_normalize().unwrap_or_default();
        // Writing into a String cannot fail.
        let _ = writeln!(
            out,
            "{},{},{},{:.4},{:.4},{:.4},{:.6},{:.6},{:.6},{:.4},{:.4}",
            child.index(),
            parent.index(),
            orders[child.index()],
            start.x,
            start.y,
            start.z,
            axis.x,
            axis.y,
            axis.z,
            length,
            skeleton.radius(child),
        );
    }
    out
}
