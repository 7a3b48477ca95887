//! The XDMF mesh reader: any text in a .xdmf file (with a valid HDF5 mesh beside it that it may
//! or may not point to) is read or rejected with a message, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

fn dir() -> &'static std::path::Path {
    static DIR: OnceLock<std::path::PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("membrane-contact-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mesh = membrane_contact::mesh::Mesh::rectangle([0.0, 0.0], [1.0, 1.0], 2, 2, membrane_contact::mesh::Diagonal::Right).unwrap();
        let f = hdf5::File::create(dir.join("m.h5")).unwrap();
        let p = ndarray::Array2::from_shape_fn((mesh.n_vertices(), 2), |(i, k)| mesh.points[i][k]);
        let c = ndarray::Array2::from_shape_fn((mesh.triangles.len(), 3), |(i, k)| mesh.triangles[i][k] as i64);
        f.new_dataset_builder().with_data(&p).create("/g").unwrap();
        f.new_dataset_builder().with_data(&c).create("/t").unwrap();
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let path = dir().join("m.xdmf");
    std::fs::write(&path, data).unwrap();
    let _ = membrane_contact::mesh::file::read(&path);
});
