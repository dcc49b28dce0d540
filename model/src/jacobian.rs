//! The exact first derivatives of a component (crate::component), in a leaf module so
//! that the physics modules that compute them (the servovalves) need not import the
//! component layer above them.

/// Exact first derivatives of a component at one state and input, dense row-major:
/// `fx` d(dx)/dx (n x n), `fu` d(dx)/du (n x m), `yx` dy/dx (p x n), `yu` dy/du (p x m).
#[derive(Debug, Clone, PartialEq)]
pub struct Jacobian {
    pub n: usize,
    pub m: usize,
    pub p: usize,
    pub fx: Vec<f64>,
    pub fu: Vec<f64>,
    pub yx: Vec<f64>,
    pub yu: Vec<f64>,
}

impl Jacobian {
    /// A zero Jacobian for `n` states, `m` inputs and `p` outputs.
    pub fn zeros(n: usize, m: usize, p: usize) -> Jacobian {
        Jacobian {
            n,
            m,
            p,
            fx: vec![0.0; n * n],
            fu: vec![0.0; n * m],
            yx: vec![0.0; p * n],
            yu: vec![0.0; p * m],
        }
    }

    /// Zero every entry (a component writes only its non-zeros).
    pub fn clear(&mut self) {
        for v in [&mut self.fx, &mut self.fu, &mut self.yx, &mut self.yu] {
            v.iter_mut().for_each(|e| *e = 0.0);
        }
    }

    pub fn fx(&mut self, i: usize, j: usize) -> &mut f64 {
        &mut self.fx[i * self.n + j]
    }
    pub fn fu(&mut self, i: usize, j: usize) -> &mut f64 {
        &mut self.fu[i * self.m + j]
    }
    pub fn yx(&mut self, i: usize, j: usize) -> &mut f64 {
        &mut self.yx[i * self.n + j]
    }
    pub fn yu(&mut self, i: usize, j: usize) -> &mut f64 {
        &mut self.yu[i * self.m + j]
    }
}
