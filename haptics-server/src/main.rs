fn main() {
    println!("haptics-server: not yet implemented");
}
