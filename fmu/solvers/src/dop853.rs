//! Dormand–Prince 8(5,3) (Hairer's DOP853): an 8th-order solution, error estimated from the
//! embedded 5th- and 3rd-order solutions together, FSAL (twelve evaluations per step), and the
//! 7th-order continuous extension, which costs three more evaluations per step that needs it.
//!
//! The coefficients are those published with the method (Hairer, Nørsett & Wanner, "Solving
//! Ordinary Differential Equations I", 2nd ed., II.10, and Hairer's DOP853 code), printed to 30
//! digits; the nearest doubles are what the method's order tests check.
// The published digits are kept as printed; Rust rounds each to the nearest double.
#![allow(clippy::excessive_precision)]

use super::adaptive::{self, Scheme, Stages};
use super::lanes;
use super::OdeSystem;

// Nodes c_i of the stages (c12 = c13 = 1).
const C2: f64 = 0.526001519587677318785587544488e-01;
const C3: f64 = 0.789002279381515978178381316732e-01;
const C4: f64 = 0.118350341907227396726757197510;
const C5: f64 = 0.281649658092772603273242802490;
const C6: f64 = 0.333333333333333333333333333333;
const C7: f64 = 0.25;
const C8: f64 = 0.307692307692307692307692307692;
const C9: f64 = 0.651282051282051282051282051282;
const C10: f64 = 0.6;
const C11: f64 = 0.857142857142857142857142857142;
const C14: f64 = 0.1;
const C15: f64 = 0.2;
const C16: f64 = 0.777777777777777777777777777778;
// Stage coefficients a_ij (stage i from stages j < i); stage 13 is the solution (B).
const A2_1: f64 = 5.26001519587677318785587544488e-2;
const A3_1: f64 = 1.97250569845378994544595329183e-2;
const A3_2: f64 = 5.91751709536136983633785987549e-2;
const A4_1: f64 = 2.95875854768068491816892993775e-2;
const A4_3: f64 = 8.87627564304205475450678981324e-2;
const A5_1: f64 = 2.41365134159266685502369798665e-1;
const A5_3: f64 = -8.84549479328286085344864962717e-1;
const A5_4: f64 = 9.24834003261792003115737966543e-1;
const A6_1: f64 = 3.7037037037037037037037037037e-2;
const A6_4: f64 = 1.70828608729473871279604482173e-1;
const A6_5: f64 = 1.25467687566822425016691814123e-1;
const A7_1: f64 = 3.7109375e-2;
const A7_4: f64 = 1.70252211019544039314978060272e-1;
const A7_5: f64 = 6.02165389804559606850219397283e-2;
const A7_6: f64 = -1.7578125e-2;
const A8_1: f64 = 3.70920001185047927108779319836e-2;
const A8_4: f64 = 1.70383925712239993810214054705e-1;
const A8_5: f64 = 1.07262030446373284651809199168e-1;
const A8_6: f64 = -1.53194377486244017527936158236e-2;
const A8_7: f64 = 8.27378916381402288758473766002e-3;
const A9_1: f64 = 6.24110958716075717114429577812e-1;
const A9_4: f64 = -3.36089262944694129406857109825;
const A9_5: f64 = -8.68219346841726006818189891453e-1;
const A9_6: f64 = 2.75920996994467083049415600797e1;
const A9_7: f64 = 2.01540675504778934086186788979e1;
const A9_8: f64 = -4.34898841810699588477366255144e1;
const A10_1: f64 = 4.77662536438264365890433908527e-1;
const A10_4: f64 = -2.48811461997166764192642586468;
const A10_5: f64 = -5.90290826836842996371446475743e-1;
const A10_6: f64 = 2.12300514481811942347288949897e1;
const A10_7: f64 = 1.52792336328824235832596922938e1;
const A10_8: f64 = -3.32882109689848629194453265587e1;
const A10_9: f64 = -2.03312017085086261358222928593e-2;
const A11_1: f64 = -9.3714243008598732571704021658e-1;
const A11_4: f64 = 5.18637242884406370830023853209;
const A11_5: f64 = 1.09143734899672957818500254654;
const A11_6: f64 = -8.14978701074692612513997267357;
const A11_7: f64 = -1.85200656599969598641566180701e1;
const A11_8: f64 = 2.27394870993505042818970056734e1;
const A11_9: f64 = 2.49360555267965238987089396762;
const A11_10: f64 = -3.0467644718982195003823669022;
const A12_1: f64 = 2.27331014751653820792359768449;
const A12_4: f64 = -1.05344954667372501984066689879e1;
const A12_5: f64 = -2.00087205822486249909675718444;
const A12_6: f64 = -1.79589318631187989172765950534e1;
const A12_7: f64 = 2.79488845294199600508499808837e1;
const A12_8: f64 = -2.85899827713502369474065508674;
const A12_9: f64 = -8.87285693353062954433549289258;
const A12_10: f64 = 1.23605671757943030647266201528e1;
const A12_11: f64 = 6.43392746015763530355970484046e-1;
const B1: f64 = 5.42937341165687622380535766363e-2;
const B6: f64 = 4.45031289275240888144113950566;
const B7: f64 = 1.89151789931450038304281599044;
const B8: f64 = -5.8012039600105847814672114227;
const B9: f64 = 3.1116436695781989440891606237e-1;
const B10: f64 = -1.52160949662516078556178806805e-1;
const B11: f64 = 2.01365400804030348374776537501e-1;
const B12: f64 = 4.47106157277725905176885569043e-2;
const A14_1: f64 = 5.61675022830479523392909219681e-2;
const A14_7: f64 = 2.53500210216624811088794765333e-1;
const A14_8: f64 = -2.46239037470802489917441475441e-1;
const A14_9: f64 = -1.24191423263816360469010140626e-1;
const A14_10: f64 = 1.5329179827876569731206322685e-1;
const A14_11: f64 = 8.20105229563468988491666602057e-3;
const A14_12: f64 = 7.56789766054569976138603589584e-3;
const A14_13: f64 = -8.298e-3;
const A15_1: f64 = 3.18346481635021405060768473261e-2;
const A15_6: f64 = 2.83009096723667755288322961402e-2;
const A15_7: f64 = 5.35419883074385676223797384372e-2;
const A15_8: f64 = -5.49237485713909884646569340306e-2;
const A15_11: f64 = -1.08347328697249322858509316994e-4;
const A15_12: f64 = 3.82571090835658412954920192323e-4;
const A15_13: f64 = -3.40465008687404560802977114492e-4;
const A15_14: f64 = 1.41312443674632500278074618366e-1;
const A16_1: f64 = -4.28896301583791923408573538692e-1;
const A16_6: f64 = -4.69762141536116384314449447206;
const A16_7: f64 = 7.68342119606259904184240953878;
const A16_8: f64 = 4.06898981839711007970213554331;
const A16_9: f64 = 3.56727187455281109270669543021e-1;
const A16_13: f64 = -1.39902416515901462129418009734e-3;
const A16_14: f64 = 2.9475147891527723389556272149;
const A16_15: f64 = -9.15095847217987001081870187138;
// The embedded 3rd-order weights subtracted from B at stages 1, 9 and 12 (BHH).
const BHH1: f64 = 0.244094488188976377952755905512;
const BHH2: f64 = 0.733846688281611857341361741547;
const BHH3: f64 = 0.220588235294117647058823529412e-1;
// The 8th-order weights minus the embedded 5th-order ones.
const ER1: f64 = 0.1312004499419488073250102996e-1;
const ER6: f64 = -0.1225156446376204440720569753e+1;
const ER7: f64 = -0.4957589496572501915214079952;
const ER8: f64 = 0.1664377182454986536961530415e+1;
const ER9: f64 = -0.3503288487499736816886487290;
const ER10: f64 = 0.3341791187130174790297318841;
const ER11: f64 = 0.8192320648511571246570742613e-1;
const ER12: f64 = -0.2235530786388629525884427845e-1;
// Dense output: rows 5 to 8 of the 7th-order continuous extension.
const D4_1: f64 = -0.84289382761090128651353491142e+1;
const D4_6: f64 = 0.56671495351937776962531783590;
const D4_7: f64 = -0.30689499459498916912797304727e+1;
const D4_8: f64 = 0.23846676565120698287728149680e+1;
const D4_9: f64 = 0.21170345824450282767155149946e+1;
const D4_10: f64 = -0.87139158377797299206789907490;
const D4_11: f64 = 0.22404374302607882758541771650e+1;
const D4_12: f64 = 0.63157877876946881815570249290;
const D4_13: f64 = -0.88990336451333310820698117400e-1;
const D4_14: f64 = 0.18148505520854727256656404962e+2;
const D4_15: f64 = -0.91946323924783554000451984436e+1;
const D4_16: f64 = -0.44360363875948939664310572000e+1;
const D5_1: f64 = 0.10427508642579134603413151009e+2;
const D5_6: f64 = 0.24228349177525818288430175319e+3;
const D5_7: f64 = 0.16520045171727028198505394887e+3;
const D5_8: f64 = -0.37454675472269020279518312152e+3;
const D5_9: f64 = -0.22113666853125306036270938578e+2;
const D5_10: f64 = 0.77334326684722638389603898808e+1;
const D5_11: f64 = -0.30674084731089398182061213626e+2;
const D5_12: f64 = -0.93321305264302278729567221706e+1;
const D5_13: f64 = 0.15697238121770843886131091075e+2;
const D5_14: f64 = -0.31139403219565177677282850411e+2;
const D5_15: f64 = -0.93529243588444783865713862664e+1;
const D5_16: f64 = 0.35816841486394083752465898540e+2;
const D6_1: f64 = 0.19985053242002433820987653617e+2;
const D6_6: f64 = -0.38703730874935176555105901742e+3;
const D6_7: f64 = -0.18917813819516756882830838328e+3;
const D6_8: f64 = 0.52780815920542364900561016686e+3;
const D6_9: f64 = -0.11573902539959630126141871134e+2;
const D6_10: f64 = 0.68812326946963000169666922661e+1;
const D6_11: f64 = -0.10006050966910838403183860980e+1;
const D6_12: f64 = 0.77771377980534432092869265740;
const D6_13: f64 = -0.27782057523535084065932004339e+1;
const D6_14: f64 = -0.60196695231264120758267380846e+2;
const D6_15: f64 = 0.84320405506677161018159903784e+2;
const D6_16: f64 = 0.11992291136182789328035130030e+2;
const D7_1: f64 = -0.25693933462703749003312586129e+2;
const D7_6: f64 = -0.15418974869023643374053993627e+3;
const D7_7: f64 = -0.23152937917604549567536039109e+3;
const D7_8: f64 = 0.35763911791061412378285349910e+3;
const D7_9: f64 = 0.93405324183624310003907691704e+2;
const D7_10: f64 = -0.37458323136451633156875139351e+2;
const D7_11: f64 = 0.10409964950896230045147246184e+3;
const D7_12: f64 = 0.29840293426660503123344363579e+2;
const D7_13: f64 = -0.43533456590011143754432175058e+2;
const D7_14: f64 = 0.96324553959188282948394950600e+2;
const D7_15: f64 = -0.39177261675615439165231486172e+2;
const D7_16: f64 = -0.14972683625798562581422125276e+3;

/// The Dormand–Prince 8(5,3) method.
pub(super) struct Dop853;

impl Scheme for Dop853 {
    const STAGES: u64 = 12;
    const LAST: usize = 11;
    const ORDER: i32 = 8;
    // Hairer's DOP853: the classical controller, shrink at most to 1/3, grow at most 6x,
    // exponent 1/8.
    const EXPO1: f64 = 1.0 / 8.0;
    const SHRINK: f64 = 0.333;
    const GROWTH: f64 = 6.0;
    const DENSE_RHS: u64 = 3;

    #[inline]
    fn step<S: OdeSystem>(
        sys: &S,
        t: f64,
        h: f64,
        t1: f64,
        x0: &[f64],
        k1: &[f64],
        k: &mut Stages,
        xs: &mut [f64],
        x1: &mut [f64],
        rtol: f64,
        atol: f64,
    ) -> f64 {
        // Slices of the model's constant size, as in Dopri5's `step`.
        let n = sys.dim();
        let [k2, k3, k4, k5, k6, k7, k8, k9, k10, k11, k12, k13, ..] = k;
        let (x0, k1, xs, x1) = (&x0[..n], &k1[..n], &mut xs[..n], &mut x1[..n]);
        let (k2, k3, k4, k5, k6, k7) = (&mut k2[..n], &mut k3[..n], &mut k4[..n], &mut k5[..n], &mut k6[..n], &mut k7[..n]);
        let (k8, k9, k10, k11, k12, k13) = (&mut k8[..n], &mut k9[..n], &mut k10[..n], &mut k11[..n], &mut k12[..n], &mut k13[..n]);
        lanes::fill!(xs, |i| x0[i] + h * (A2_1 * k1[i]));
        sys.rhs(t + C2 * h, xs, k2);
        lanes::fill!(xs, |i| x0[i] + h * (A3_1 * k1[i] + A3_2 * k2[i]));
        sys.rhs(t + C3 * h, xs, k3);
        lanes::fill!(xs, |i| x0[i] + h * (A4_1 * k1[i] + A4_3 * k3[i]));
        sys.rhs(t + C4 * h, xs, k4);
        lanes::fill!(xs, |i| x0[i] + h * (A5_1 * k1[i] + A5_3 * k3[i] + A5_4 * k4[i]));
        sys.rhs(t + C5 * h, xs, k5);
        lanes::fill!(xs, |i| x0[i] + h * (A6_1 * k1[i] + A6_4 * k4[i] + A6_5 * k5[i]));
        sys.rhs(t + C6 * h, xs, k6);
        lanes::fill!(xs, |i| x0[i] + h * (A7_1 * k1[i] + A7_4 * k4[i] + A7_5 * k5[i] + A7_6 * k6[i]));
        sys.rhs(t + C7 * h, xs, k7);
        lanes::fill!(xs, |i| x0[i] + h * (A8_1 * k1[i] + A8_4 * k4[i] + A8_5 * k5[i] + A8_6 * k6[i] + A8_7 * k7[i]));
        sys.rhs(t + C8 * h, xs, k8);
        lanes::fill!(xs, |i| x0[i] + h * (A9_1 * k1[i] + A9_4 * k4[i] + A9_5 * k5[i] + A9_6 * k6[i] + A9_7 * k7[i] + A9_8 * k8[i]));
        sys.rhs(t + C9 * h, xs, k9);
        lanes::fill!(xs, |i| x0[i]
            + h * (A10_1 * k1[i] + A10_4 * k4[i] + A10_5 * k5[i] + A10_6 * k6[i] + A10_7 * k7[i] + A10_8 * k8[i] + A10_9 * k9[i]));
        sys.rhs(t + C10 * h, xs, k10);
        lanes::fill!(xs, |i| x0[i]
            + h * (A11_1 * k1[i]
                + A11_4 * k4[i]
                + A11_5 * k5[i]
                + A11_6 * k6[i]
                + A11_7 * k7[i]
                + A11_8 * k8[i]
                + A11_9 * k9[i]
                + A11_10 * k10[i]));
        sys.rhs(t + C11 * h, xs, k11);
        lanes::fill!(xs, |i| x0[i]
            + h * (A12_1 * k1[i]
                + A12_4 * k4[i]
                + A12_5 * k5[i]
                + A12_6 * k6[i]
                + A12_7 * k7[i]
                + A12_8 * k8[i]
                + A12_9 * k9[i]
                + A12_10 * k10[i]
                + A12_11 * k11[i]));
        sys.rhs(t1, xs, k12);
        lanes::fill!(x1, |i| x0[i]
            + h * (B1 * k1[i] + B6 * k6[i] + B7 * k7[i] + B8 * k8[i] + B9 * k9[i] + B10 * k10[i] + B11 * k11[i] + B12 * k12[i]));
        sys.rhs(t1, x1, k13);
        // Hairer's estimate: the 5th-order error, scaled down where the 3rd-order one is much
        // larger (err5^2 / sqrt(err5^2 + 0.01 err3^2)), so it is of the 8th order's size.
        let (mut err5, mut err3) = (0.0, 0.0);
        for i in 0..n {
            let e5 = ER1 * k1[i] + ER6 * k6[i] + ER7 * k7[i] + ER8 * k8[i] + ER9 * k9[i] + ER10 * k10[i] + ER11 * k11[i] + ER12 * k12[i];
            let high = B1 * k1[i] + B6 * k6[i] + B7 * k7[i] + B8 * k8[i] + B9 * k9[i] + B10 * k10[i] + B11 * k11[i] + B12 * k12[i];
            let e3 = high - BHH1 * k1[i] - BHH2 * k9[i] - BHH3 * k12[i];
            let sk = adaptive::weight(atol, rtol, x0[i], x1[i]);
            err5 += (e5 / sk) * (e5 / sk);
            err3 += (e3 / sk) * (e3 / sk);
        }
        if n == 0 {
            return 0.0;
        }
        let deno = err5 + 0.01 * err3;
        let deno = if deno > 0.0 { deno } else { 1.0 };
        h.abs() * err5 * (1.0 / (n as f64 * deno)).sqrt()
    }

    /// Evaluates the three extra stages, then the eight coefficient vectors (Hairer's
    /// rcont1..8): x0, x1 - x0, the cubic Hermite corrections, and four higher terms.
    #[inline]
    fn fill_dense<S: OdeSystem>(
        sys: &S,
        t: f64,
        h: f64,
        x0: &[f64],
        x1: &[f64],
        k1: &[f64],
        k: &mut Stages,
        xs: &mut [f64],
        dense: &mut [f64],
    ) {
        let n = sys.dim();
        let [_, _, _, _, k6, k7, k8, k9, k10, k11, k12, k13, k14, k15, k16] = k;
        let (x0, x1, k1, xs) = (&x0[..n], &x1[..n], &k1[..n], &mut xs[..n]);
        let (k6, k7, k8, k9, k10) = (&k6[..n], &k7[..n], &k8[..n], &k9[..n], &k10[..n]);
        let (k11, k12, k13) = (&k11[..n], &k12[..n], &k13[..n]);
        let (k14, k15, k16) = (&mut k14[..n], &mut k15[..n], &mut k16[..n]);
        lanes::fill!(xs, |i| x0[i]
            + h * (A14_1 * k1[i]
                + A14_7 * k7[i]
                + A14_8 * k8[i]
                + A14_9 * k9[i]
                + A14_10 * k10[i]
                + A14_11 * k11[i]
                + A14_12 * k12[i]
                + A14_13 * k13[i]));
        sys.rhs(t + C14 * h, xs, k14);
        lanes::fill!(xs, |i| x0[i]
            + h * (A15_1 * k1[i]
                + A15_6 * k6[i]
                + A15_7 * k7[i]
                + A15_8 * k8[i]
                + A15_11 * k11[i]
                + A15_12 * k12[i]
                + A15_13 * k13[i]
                + A15_14 * k14[i]));
        sys.rhs(t + C15 * h, xs, k15);
        lanes::fill!(xs, |i| x0[i]
            + h * (A16_1 * k1[i]
                + A16_6 * k6[i]
                + A16_7 * k7[i]
                + A16_8 * k8[i]
                + A16_9 * k9[i]
                + A16_13 * k13[i]
                + A16_14 * k14[i]
                + A16_15 * k15[i]));
        sys.rhs(t + C16 * h, xs, k16);
        let (r, rest) = dense.split_at_mut(4 * n);
        let (r4, rest) = rest.split_at_mut(n);
        let (r5, rest) = rest.split_at_mut(n);
        let (r6, rest) = rest.split_at_mut(n);
        let r7 = &mut rest[..n];
        let (r0, rest) = r.split_at_mut(n);
        let (r1, rest) = rest.split_at_mut(n);
        let (r2, r3) = rest.split_at_mut(n);
        lanes::fill!(r0, |i| x0[i]);
        lanes::fill!(r1, |i| x1[i] - x0[i]);
        lanes::fill!(r2, |i| h * k1[i] - (x1[i] - x0[i]));
        lanes::fill!(r3, |i| {
            let ydiff = x1[i] - x0[i];
            ydiff - h * k13[i] - (h * k1[i] - ydiff)
        });
        lanes::fill!(r4, |i| h
            * (D4_1 * k1[i]
                + D4_6 * k6[i]
                + D4_7 * k7[i]
                + D4_8 * k8[i]
                + D4_9 * k9[i]
                + D4_10 * k10[i]
                + D4_11 * k11[i]
                + D4_12 * k12[i]
                + D4_13 * k13[i]
                + D4_14 * k14[i]
                + D4_15 * k15[i]
                + D4_16 * k16[i]));
        lanes::fill!(r5, |i| h
            * (D5_1 * k1[i]
                + D5_6 * k6[i]
                + D5_7 * k7[i]
                + D5_8 * k8[i]
                + D5_9 * k9[i]
                + D5_10 * k10[i]
                + D5_11 * k11[i]
                + D5_12 * k12[i]
                + D5_13 * k13[i]
                + D5_14 * k14[i]
                + D5_15 * k15[i]
                + D5_16 * k16[i]));
        lanes::fill!(r6, |i| h
            * (D6_1 * k1[i]
                + D6_6 * k6[i]
                + D6_7 * k7[i]
                + D6_8 * k8[i]
                + D6_9 * k9[i]
                + D6_10 * k10[i]
                + D6_11 * k11[i]
                + D6_12 * k12[i]
                + D6_13 * k13[i]
                + D6_14 * k14[i]
                + D6_15 * k15[i]
                + D6_16 * k16[i]));
        lanes::fill!(r7, |i| h
            * (D7_1 * k1[i]
                + D7_6 * k6[i]
                + D7_7 * k7[i]
                + D7_8 * k8[i]
                + D7_9 * k9[i]
                + D7_10 * k10[i]
                + D7_11 * k11[i]
                + D7_12 * k12[i]
                + D7_13 * k13[i]
                + D7_14 * k14[i]
                + D7_15 * k15[i]
                + D7_16 * k16[i]));
    }

    // Inlined where `n` is the model's constant: unrolled, no bounds checks (one per communication point).
    #[inline(always)]
    fn eval(th: f64, n: usize, dense: &[f64], out: &mut [f64]) {
        let th1 = 1.0 - th;
        let r = |c: usize| &dense[c * n..(c + 1) * n];
        let (r0, r1, r2, r3, r4, r5, r6, r7) = (r(0), r(1), r(2), r(3), r(4), r(5), r(6), r(7));
        lanes::fill!(&mut out[..n], |i| {
            let high = r4[i] + th * (r5[i] + th1 * (r6[i] + th * r7[i]));
            r0[i] + th * (r1[i] + th1 * (r2[i] + th * (r3[i] + th1 * high)))
        });
    }
}
