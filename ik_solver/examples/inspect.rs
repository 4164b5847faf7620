//! Prints what the model finds in a URDF: `cargo run -p ik_solver --example inspect -- FILE`.
fn main() {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/../config/biped.urdf").into());
    match ik_solver::BipedModel::from_urdf_file(&path, None) {
        Ok(b) => {
            println!(
                "robot {} mass {:.4} kg, {} dofs",
                b.robot().name(),
                b.robot().total_mass_kg(),
                b.robot().dof_count()
            );
            for s in ik_solver::Side::BOTH {
                println!("{:#?}", b.leg(s));
            }
        }
        Err(e) => println!("error: {e}"),
    }
}
