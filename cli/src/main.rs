//! `deepcontact`: simulate the thesis scenes, compare warm starts, and more.

fn main() {
    deepcontact_cli::main_with(deepcontact_experiments::full_registry());
}
