//! Components joined port to port into one state vector, with the exact Jacobian of the
//! whole by the chain rule over the connections.
//!
//! Each block owns a contiguous slice of the state vector; each of its inputs comes from
//! another block's output, from an external input of the composition, or is a constant.
//! The port-causality rule leaves no algebraic loop between signals, but it may between
//! blocks (the manifold's port pressures feed the valves, whose flows feed the manifold's
//! chamber flows): the `schedule` lists block evaluations in an order that computes every
//! signal after those it depends on, a block appearing more than once if need be, each
//! time for the outputs it names.

use std::ops::Range;

use super::{Component, Jacobian, State};

/// Where an input of a block comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Source {
    /// Output `port` of block `block`.
    Output { block: usize, port: usize },
    /// External input `k` of the composition.
    External(usize),
    /// A value fixed when the composition was built (a supply pressure).
    Constant(f64),
}

#[derive(Debug)]
struct Block {
    component: Box<dyn Component>,
    /// First state of the block in the composed vector.
    offset: usize,
    /// First output of the block among the signals.
    signal: usize,
    sources: Vec<Source>,
    /// Numbers of states, inputs and outputs.
    sizes: (usize, usize, usize),
}

/// Most inputs or outputs of one block, and most signals of a composition: stack
/// buffers of these sizes keep the right-hand side free of allocation. The bench's
/// manifold has the most ports (6) and the bench 16 signals.
const MAX_PORTS: usize = 8;
const MAX_SIGNALS: usize = 32;

/// Components joined into one system `dx/dt = f(x, external)`.
#[derive(Debug)]
pub struct Composition {
    blocks: Vec<Block>,
    schedule: Vec<(usize, Range<usize>)>,
    states: Vec<State>,
    n_signals: usize,
}

impl Composition {
    /// Join `blocks` (each with the sources of its inputs), evaluating outputs in the
    /// order `schedule` (block, outputs to evaluate). Panics on a connection that names
    /// no port: compositions are built by the model's own code, so that is a programming
    /// error, caught by tests.
    pub fn new(
        blocks: Vec<(Box<dyn Component>, Vec<Source>)>,
        schedule: Vec<(usize, Range<usize>)>,
    ) -> Self {
        let mut states = Vec::new();
        let mut n_signals = 0;
        let blocks: Vec<Block> = blocks
            .into_iter()
            .map(|(component, sources)| {
                assert_eq!(sources.len(), component.inputs().len(), "{component:?}");
                assert!(component.inputs().len() <= MAX_PORTS);
                assert!(component.outputs().len() <= MAX_PORTS);
                let c = &component;
                let b = Block {
                    offset: states.len(),
                    signal: n_signals,
                    sources,
                    sizes: (c.states().len(), c.inputs().len(), c.outputs().len()),
                    component,
                };
                states.extend_from_slice(b.component.states());
                n_signals += b.component.outputs().len();
                b
            })
            .collect();
        assert!(n_signals <= MAX_SIGNALS);
        for b in &blocks {
            for s in &b.sources {
                if let Source::Output { block, port } = *s {
                    assert!(port < blocks[block].component.outputs().len());
                }
            }
        }
        Composition {
            blocks,
            schedule,
            states,
            n_signals,
        }
    }

    /// The states of every block, in order.
    pub fn states(&self) -> &[State] {
        &self.states
    }

    pub fn n_states(&self) -> usize {
        self.states.len()
    }

    /// Component `k` and the range of its states.
    pub fn block(&self, k: usize) -> (&dyn Component, std::ops::Range<usize>) {
        let b = &self.blocks[k];
        let n = b.component.states().len();
        (b.component.as_ref(), b.offset..b.offset + n)
    }

    fn input(&self, s: &Source, signals: &[f64], external: &[f64]) -> f64 {
        match *s {
            Source::Output { block, port } => signals[self.blocks[block].signal + port],
            Source::External(k) => external[k],
            Source::Constant(v) => v,
        }
    }

    fn gather(&self, b: &Block, signals: &[f64], external: &[f64], u: &mut [f64; MAX_PORTS]) {
        for (ui, s) in u.iter_mut().zip(&b.sources) {
            *ui = self.input(s, signals, external);
        }
    }

    /// Every output of every block at state `x`, in the schedule's order; the last
    /// evaluation also gives its block's derivatives when `dx` is given (its inputs are
    /// then final), which spares a component work its outputs and derivatives share.
    fn evaluate(
        &self,
        x: &[f64],
        external: &[f64],
        signals: &mut [f64],
        mut dx: Option<&mut [f64]>,
    ) {
        let mut u = [0.0; MAX_PORTS];
        let last = self.schedule.len().saturating_sub(1);
        for (i, (k, which)) in self.schedule.iter().enumerate() {
            let b = &self.blocks[*k];
            self.gather(b, signals, external, &mut u);
            let (n, m, p) = self.sizes(b);
            let y = &mut signals[b.signal..b.signal + p];
            let r = b.offset..b.offset + n;
            match dx.as_deref_mut() {
                Some(dx) if i == last => b.component.derivatives_and_outputs(
                    &x[r.clone()],
                    &u[..m],
                    which.clone(),
                    &mut dx[r],
                    y,
                ),
                _ => b.component.outputs_of(&x[r], &u[..m], which.clone(), y),
            }
        }
    }

    /// Every output of every block at state `x`, in the schedule's order.
    pub fn signals(&self, x: &[f64], external: &[f64], signals: &mut [f64]) {
        self.evaluate(x, external, signals, None)
    }

    fn sizes(&self, b: &Block) -> (usize, usize, usize) {
        b.sizes
    }

    /// Output `port` of block `block` among the signals.
    pub fn signal(&self, signals: &[f64], block: usize, port: usize) -> f64 {
        signals[self.blocks[block].signal + port]
    }

    /// The composed right-hand side; returns the signals it went through, which the
    /// caller may read with [`Composition::signal`].
    pub fn derivatives(&self, x: &[f64], external: &[f64], dx: &mut [f64]) -> [f64; MAX_SIGNALS] {
        let mut signals = [0.0; MAX_SIGNALS];
        self.evaluate(x, external, &mut signals[..self.n_signals], Some(&mut *dx));
        let done = self.schedule.last().map(|(k, _)| *k);
        let mut u = [0.0; MAX_PORTS];
        for (k, b) in self.blocks.iter().enumerate() {
            if Some(k) == done {
                continue;
            }
            let (n, m, _) = self.sizes(b);
            if n == 0 {
                continue; // a static valve
            }
            self.gather(b, &signals, external, &mut u);
            let r = b.offset..b.offset + n;
            b.component.derivatives(&x[r.clone()], &u[..m], &mut dx[r]);
        }
        signals
    }

    /// d(dx_i)/d(x_j) of the composition, row-major `n x n`, by the chain rule: each
    /// signal's gradient with respect to the composed state is its block's `yx` on the
    /// block's own states plus `yu` times the gradients of its inputs.
    pub fn jacobian(&self, x: &[f64], external: &[f64], jac: &mut [f64]) {
        let n = self.n_states();
        jac.iter_mut().for_each(|e| *e = 0.0);
        let mut signals = [0.0; MAX_SIGNALS];
        // gradients of the signals with respect to x, row-major n_signals x n
        let mut grad = vec![0.0; self.n_signals * n];
        let mut u = [0.0; MAX_PORTS];
        let mut local: Vec<Option<Jacobian>> = (0..self.blocks.len()).map(|_| None).collect();
        // one pass of the schedule for values, gradients follow the same order
        for &(k, _) in &self.schedule {
            let b = &self.blocks[k];
            let (nb, m, p) = self.sizes(b);
            self.gather(b, &signals, external, &mut u);
            let xb = &x[b.offset..b.offset + nb];
            b.component
                .outputs_at(xb, &u[..m], &mut signals[b.signal..b.signal + p]);
            let j = local[k].get_or_insert_with(|| Jacobian::zeros(nb, m, p));
            j.clear();
            b.component.jacobian(xb, &u[..m], j);
            let input_grad = self.input_gradients(b, &grad, n);
            for o in 0..p {
                let row = (b.signal + o) * n;
                let g = &mut grad[row..row + n];
                g.iter_mut().for_each(|e| *e = 0.0);
                for s in 0..nb {
                    g[b.offset + s] += j.yx[o * nb + s];
                }
                for (i, ig) in input_grad.iter().enumerate() {
                    let d = j.yu[o * m + i];
                    if d != 0.0 {
                        g.iter_mut().zip(ig).for_each(|(e, v)| *e += d * v);
                    }
                }
            }
        }
        for (k, b) in self.blocks.iter().enumerate() {
            let (nb, m, p) = self.sizes(b);
            let j = local[k].get_or_insert_with(|| Jacobian::zeros(nb, m, p));
            self.gather(b, &signals, external, &mut u);
            j.clear();
            let xb = &x[b.offset..b.offset + nb];
            b.component.jacobian(xb, &u[..m], j);
            let input_grad = self.input_gradients(b, &grad, n);
            for r in 0..nb {
                let row = &mut jac[(b.offset + r) * n..(b.offset + r + 1) * n];
                for s in 0..nb {
                    row[b.offset + s] += j.fx[r * nb + s];
                }
                for (i, ig) in input_grad.iter().enumerate() {
                    let d = j.fu[r * m + i];
                    if d != 0.0 {
                        row.iter_mut().zip(ig).for_each(|(e, v)| *e += d * v);
                    }
                }
            }
        }
    }

    /// Gradients of a block's inputs with respect to the composed state (zero for
    /// external inputs and constants).
    fn input_gradients(&self, b: &Block, grad: &[f64], n: usize) -> Vec<Vec<f64>> {
        b.sources
            .iter()
            .map(|s| match *s {
                Source::Output { block, port } => {
                    let row = self.blocks[block].signal + port;
                    grad[row * n..(row + 1) * n].to_vec()
                }
                _ => vec![0.0; n],
            })
            .collect()
    }
}
