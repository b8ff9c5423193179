fn main() {
    println!("dynid");
}
