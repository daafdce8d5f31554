//! Writes the scene the format fixtures are made from (tests/data/formats,
//! see scripts/format-fixtures.sh): `cargo run -p srug-tests --example format_source OUT.ply`.

fn main() -> Result<(), srug::Error> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "source.ply".into());
    srug::io::write_ply(out, &srug_tests::format_source_scene(), srug::io::PlyFormat::BinaryLittleEndian)
}
