// A valid model compiles, and its evaluator computes the basis functions per sample.
use dynid::runtime::BasisEval;

dynid::model! {
    model sdof {
        body m1 { mass = 1.0 }
        input u on m1
        param d ~ 0.4
        param k ~ 4.0
        param k3 ~ 2.0
        spring k1 (ground, m1) = k * s + k3 * s^3
        damper d1 (ground, m1) = d * v
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
    assert_eq!(SdofParams::default().to_vec(), vec![0.4, 4.0, 2.0]);
}
