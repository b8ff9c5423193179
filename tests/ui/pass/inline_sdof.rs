// A valid model compiles; its evaluator and conveniences are usable.
use dynid::runtime::BasisEval;

dynid::model! {
    model sdof {
        body m1 = 1.0
        input u on m1
        spring k (ground, m1) ~ 4.0
        damper d (ground, m1) ~ 0.4
        force nl (ground, m1) = k3 ~ 2.0 * s^3
        excite u: lowpass(corner = 10) levels [6, 15]
    }
}

fn main() {
    let model = Sdof::new();
    let n = model.n_roots();
    assert_eq!(n, model.ir().eval_roots().len());
    let x = [0.5, -1.0];
    let v = [0.0, 2.0];
    let u = [1.0, 1.0];
    let mut out = vec![0.0; n * 2];
    model.eval_block(&[&x, &v, &u], 2, &mut out, &mut Vec::new());
    assert_eq!(SdofParams::default().to_vec(), vec![4.0, 0.4, 2.0]);
    let _: fn(&Sdof, &[dynid::runtime::record::Record]) -> Result<_, _> = Sdof::identify;
}
