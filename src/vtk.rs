//! VTK XML PolyData (`.vtp`) for particle and material-point snapshots, readable by
//! ParaView (use the "Point Gaussian" representation with `radius` as scale array).
//! Pure formatting: the caller writes the returned string to a file atomically.

use std::fmt::Write;

/// One per-point data array.
#[derive(Debug, Clone, Copy)]
pub enum Field<'a> {
    /// One value per point.
    Scalar(&'a [f64]),
    /// Two components per point (x, y); written as 3-component vectors with z = 0.
    Vector(&'a [f64], &'a [f64]),
    /// Symmetric 2×2 tensor per point (xx, yy, xy); written as 6 components
    /// (xx, yy, zz = 0, xy, yz = 0, xz = 0), ParaView's symmetric-tensor order.
    SymTensor(&'a [f64], &'a [f64], &'a [f64]),
}

/// Render points at (x, y, 0) with named point-data arrays as an ASCII `.vtp` document.
/// Every array must have one entry per point.
pub fn polydata(x: &[f64], y: &[f64], fields: &[(&str, Field)]) -> String {
    let n = x.len();
    assert_eq!(y.len(), n, "vtk: x and y differ in length");
    let mut s = String::with_capacity(64 * n * (1 + fields.len()));
    s.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\">\n<PolyData>\n");
    let _ = writeln!(
        s,
        "<Piece NumberOfPoints=\"{n}\" NumberOfVerts=\"{n}\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">"
    );
    s.push_str("<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n");
    for i in 0..n {
        let _ = writeln!(s, "{:e} {:e} 0", x[i], y[i]);
    }
    s.push_str("</DataArray>\n</Points>\n<Verts>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for i in 0..n {
        let _ = write!(s, "{i} ");
    }
    s.push_str("\n</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    for i in 0..n {
        let _ = write!(s, "{} ", i + 1);
    }
    s.push_str("\n</DataArray>\n</Verts>\n<PointData>\n");
    for (name, f) in fields {
        match f {
            Field::Scalar(v) => {
                assert_eq!(v.len(), n, "vtk: field {name} has the wrong length");
                let _ = writeln!(s, "<DataArray type=\"Float64\" Name=\"{name}\" format=\"ascii\">");
                for a in v.iter() {
                    let _ = writeln!(s, "{a:e}");
                }
            }
            Field::Vector(a, b) => {
                assert!(a.len() == n && b.len() == n, "vtk: field {name} has the wrong length");
                let _ = writeln!(
                    s,
                    "<DataArray type=\"Float64\" Name=\"{name}\" NumberOfComponents=\"3\" format=\"ascii\">"
                );
                for i in 0..n {
                    let _ = writeln!(s, "{:e} {:e} 0", a[i], b[i]);
                }
            }
            Field::SymTensor(xx, yy, xy) => {
                assert!(
                    xx.len() == n && yy.len() == n && xy.len() == n,
                    "vtk: field {name} has the wrong length"
                );
                let _ = writeln!(
                    s,
                    "<DataArray type=\"Float64\" Name=\"{name}\" NumberOfComponents=\"6\" format=\"ascii\">"
                );
                for i in 0..n {
                    let _ = writeln!(s, "{:e} {:e} 0 {:e} 0 0", xx[i], yy[i], xy[i]);
                }
            }
        }
        s.push_str("</DataArray>\n");
    }
    s.push_str("</PointData>\n</Piece>\n</PolyData>\n</VTKFile>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn well_formed_counts() {
        let x = [0.0, 1.0];
        let y = [0.0, 2.0];
        let r = [0.5, 0.5];
        let s = polydata(
            &x,
            &y,
            &[("radius", Field::Scalar(&r)), ("velocity", Field::Vector(&x, &y))],
        );
        assert!(s.contains("NumberOfPoints=\"2\""));
        assert_eq!(s.matches("<DataArray").count(), 5);
        assert_eq!(s.matches("</DataArray>").count(), 5);
        assert!(s.trim_end().ends_with("</VTKFile>"));
    }
}
