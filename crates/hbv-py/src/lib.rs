//! The Python module `hbv._hbv`, re-exported by the package `hbv` (`python/hbv/__init__.py`).
//!
//! A thin layer: NumPy arrays are checked and read in place (`arrays.rs`), trees are built with
//! the options of the command line (`build_options.rs`), and every query is the library's own,
//! run on all cores with the GIL released (`bvh.rs`, `thread_pool.rs`); scenes of many meshes
//! placed by instances are `scene.rs` (their files and pickles `scene_file.rs`). Answer arrays are Rust vectors handed to NumPy, from an
//! allocator that keeps freed pages (`allocator.rs`).

use pyo3::prelude::*;

mod allocator;
mod array_rows;
mod arrays;
mod build_options;
mod bvh;
mod bvh_file;
mod grid;
mod masks;
mod mesh;
mod mesh_inside;
mod output_column;
mod plane_locations;
mod ray_queries;
mod scene;
mod scene_arguments;
mod scene_file;
mod scene_queries;
mod thread_pool;

#[pymodule]
fn _hbv(m: &Bound<'_, PyModule>) -> PyResult<()> {
    allocator::configure();
    m.add_class::<mesh::PyMesh>()?;
    m.add_class::<bvh::PyBvh>()?;
    m.add_class::<grid::PyGrid>()?;
    m.add_class::<scene::PyScene>()?;
    m.add_function(wrap_pyfunction!(bvh_file::load_bvh, m)?)?;
    m.add_function(wrap_pyfunction!(bvh_file::_bvh_from_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::load, m)?)?;
    m.add_function(wrap_pyfunction!(plane_locations::trimesh_hits, m)?)?;
    m.add_function(wrap_pyfunction!(scene_file::load_scene, m)?)?;
    m.add_function(wrap_pyfunction!(scene_file::_scene_from_bytes, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
