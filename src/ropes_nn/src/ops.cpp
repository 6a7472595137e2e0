#include "ropes_nn/ops.hpp"

#ifdef __AVX__
#include <immintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>

#include "gemm.hpp"
#include "ropes_nn/parallel.hpp"
#include "tensor_impl.hpp"

namespace ropes::nn {

namespace {

using Grads = std::vector<Tensor>;
using BackwardFn = std::function<Grads(const std::vector<Tensor>& inputs, const Tensor& g)>;

// a node whose backward is a function of the inputs and the output gradient; it must not
// capture the output tensor (that would make a reference cycle)
class FnNode final : public Node {
 public:
  FnNode(const char* name, BackwardFn fn) : name_(name), fn_(std::move(fn)) {}
  const char* name() const override { return name_; }
  std::vector<Tensor> backward(const Tensor& g) override { return fn_(inputs, g); }

 private:
  const char* name_;
  BackwardFn fn_;
};

// the result of an operation, with its backward recorded when needed; without a graph
// neither the node nor the list of inputs is built (no allocation beyond the result's)
template <typename Fn>
Tensor record(const Shape& shape, Buffer values, std::initializer_list<Tensor> inputs,
              const char* name, Fn&& fn) {
  if (!graph_needed(inputs))
    return Tensor(shape, std::move(values));
  return make_op_result(shape, std::move(values),
                        std::make_shared<FnNode>(name, BackwardFn(std::forward<Fn>(fn))),
                        std::vector<Tensor>(inputs));
}
template <typename Fn>
Tensor record(const Shape& shape, Buffer values, const std::vector<Tensor>& inputs,
              const char* name, Fn&& fn) {
  if (!graph_needed(inputs))
    return Tensor(shape, std::move(values));
  return make_op_result(shape, std::move(values),
                        std::make_shared<FnNode>(name, BackwardFn(std::forward<Fn>(fn))), inputs);
}

void require_defined(const Tensor& t, const char* op, const char* arg) {
  if (!t.defined())
    throw std::invalid_argument(std::string(op) + ": " + arg + " is undefined");
}

// shapes right-aligned to rank 4
using Dims4 = std::array<std::int64_t, 4>;
Dims4 align4(const Shape& s) {
  Dims4 d = {1, 1, 1, 1};
  for (int i = 0; i < s.rank(); ++i)
    d[static_cast<std::size_t>(4 - s.rank() + i)] = s[i];
  return d;
}
// element strides of a contiguous `src` read as `out`: 0 along stretched dimensions
Dims4 broadcast_strides(const Dims4& src, const Dims4& out) {
  Dims4 strides{};
  std::int64_t stride = 1;
  for (int i = 3; i >= 0; --i) {
    const auto k = static_cast<std::size_t>(i);
    strides[k] = (src[k] == 1 && out[k] != 1) ? 0 : stride;
    stride *= src[k];
  }
  return strides;
}

// elementwise loops split over threads when large enough to pay for it (pure elementwise
// work: the result does not depend on the split)
constexpr std::int64_t kParallelElements = 1 << 15;

template <typename Body>
void elementwise_for(std::int64_t n, Body body) {
  if (n < kParallelElements) {
    body(0, n);
  } else {
    parallel_for(n, [&](int, std::int64_t begin, std::int64_t end) { body(begin, end); });
  }
}

template <typename F>
Buffer broadcast_apply(const Tensor& a, const Tensor& b, const Shape& out, F f) {
  const std::int64_t n = out.numel();
  Buffer r(static_cast<std::size_t>(n));
  float* pr = r.data();
  const float* pa = a.data();
  const float* pb = b.data();
  if (a.shape() == out && b.shape() == out) {
    elementwise_for(n, [&](std::int64_t begin, std::int64_t end) {
      for (std::int64_t i = begin; i < end; ++i)
        pr[i] = f(pa[i], pb[i]);
    });
    return r;
  }
  if (a.shape() == out && b.numel() == 1) {
    const float vb = pb[0];
    elementwise_for(n, [&](std::int64_t begin, std::int64_t end) {
      for (std::int64_t i = begin; i < end; ++i)
        pr[i] = f(pa[i], vb);
    });
    return r;
  }
  const Dims4 od = align4(out);
  const Dims4 sa = broadcast_strides(align4(a.shape()), od);
  const Dims4 sb = broadcast_strides(align4(b.shape()), od);
  if (a.shape() == out && sb[2] == 0 && sb[3] == 0) {
    // b constant over the last two axes (a channel bias): planes of od[2] * od[3] elements
    const std::int64_t plane = od[2] * od[3];
    const auto planes = [&](std::int64_t begin, std::int64_t end) {
      for (std::int64_t q = begin; q < end; ++q) {
        const float vb = pb[q / od[1] * sb[0] + q % od[1] * sb[1]];
        const float* ra = pa + q * plane;
        float* rr = pr + q * plane;
        for (std::int64_t i = 0; i < plane; ++i)
          rr[i] = f(ra[i], vb);
      }
    };
    if (n < kParallelElements)
      planes(0, od[0] * od[1]);
    else
      parallel_for(od[0] * od[1],
                   [&](int, std::int64_t begin, std::int64_t end) { planes(begin, end); });
    return r;
  }
  // general case: rows of the innermost axis, split over threads by row
  const std::int64_t rows = od[0] * od[1] * od[2];
  const auto run = [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t row = begin; row < end; ++row) {
      const std::int64_t i2 = row % od[2], i1 = (row / od[2]) % od[1], i0 = row / (od[2] * od[1]);
      const float* ra = pa + i0 * sa[0] + i1 * sa[1] + i2 * sa[2];
      const float* rb = pb + i0 * sb[0] + i1 * sb[1] + i2 * sb[2];
      float* rr = pr + row * od[3];
      if (sa[3] == 1 && sb[3] == 0) {
        const float vb = rb[0];
        for (std::int64_t i3 = 0; i3 < od[3]; ++i3)
          rr[i3] = f(ra[i3], vb);
      } else {
        for (std::int64_t i3 = 0; i3 < od[3]; ++i3)
          rr[i3] = f(ra[i3 * sa[3]], rb[i3 * sb[3]]);
      }
    }
  };
  if (n < kParallelElements) {
    run(0, rows);
  } else {
    parallel_for(rows, [&](int, std::int64_t begin, std::int64_t end) { run(begin, end); });
  }
  return r;
}

// f of each of x's values, in a new buffer (on the threads for large tensors)
template <typename F>
Buffer map_values(const Tensor& x, F f) {
  Buffer r(static_cast<std::size_t>(x.numel()));
  float* pr = r.data();
  const float* p = x.data();
  elementwise_for(x.numel(), [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t i = begin; i < end; ++i)
      pr[i] = f(p[i]);
  });
  return r;
}

template <typename F, typename B>
Tensor unary(const Tensor& x, const char* name, F f, B&& backward) {
  require_defined(x, name, "x");
  return record(x.shape(), map_values(x, f), {x}, name, std::forward<B>(backward));
}

// a constant tensor (no graph) computed elementwise from x's values
template <typename F>
Tensor constant_map(const Tensor& x, F f) {
  return Tensor(x.shape(), map_values(x, f));
}

// g masked where x <= 0, in one pass: relu's backward when no graph is recorded
Tensor masked_by_positive(const Tensor& g, const Tensor& x) {
  Buffer r(static_cast<std::size_t>(x.numel()));
  float* pr = r.data();
  const float* pg = g.data();
  const float* px = x.data();
  elementwise_for(x.numel(), [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t i = begin; i < end; ++i)
      pr[i] = px[i] > 0.0f ? pg[i] : 0.0f;
  });
  return Tensor(x.shape(), std::move(r));
}

int normalize_axis(int axis, int rank, const char* op) {
  const int a = axis < 0 ? axis + rank : axis;
  if (a < 0 || a >= rank) {
    throw std::invalid_argument(std::string(op) + ": axis " + std::to_string(axis) +
                                " is out of range for rank " + std::to_string(rank));
  }
  return a;
}

// sums x over the aligned-rank-4 axes marked in `reduce`; the result has the rank-4 shape
// with those axes set to 1 (row-major), accumulated in double. Each output's sum runs over its
// elements in x's order from 0.0, one addition at a time (what one pass over x in order gives
// it), so its bits do not depend on how the outputs are spread: four outputs' sums are
// interleaved (independent chains of additions) and groups of outputs go to the threads.
Buffer reduce_sum4(const Tensor& x, const std::array<bool, 4>& reduce, Dims4* out_dims) {
  const Dims4 xd = align4(x.shape());
  Dims4 od = xd, extent{};
  const Dims4 xs = {xd[1] * xd[2] * xd[3], xd[2] * xd[3], xd[3], 1};
  for (std::size_t i = 0; i < 4; ++i) {
    od[i] = reduce[i] ? 1 : xd[i];
    extent[i] = reduce[i] ? xd[i] : 1;
  }
  const std::int64_t outputs = od[0] * od[1] * od[2] * od[3];
  Buffer r(static_cast<std::size_t>(outputs));
  const float* p = x.data();
  constexpr std::int64_t kChains = 4;
  const std::int64_t groups = (outputs + kChains - 1) / kChains;
  const auto sum_groups = [&](std::int64_t first, std::int64_t last) {
    for (std::int64_t group = first; group < last; ++group) {
      const std::int64_t o0 = group * kChains;
      const std::int64_t count = std::min(kChains, outputs - o0);
      std::int64_t base[kChains];
      double acc[kChains] = {};
      for (std::int64_t j = 0; j < kChains; ++j) {
        // output o's index along each kept axis (row-major over od), a padding chain
        // repeating the last output
        std::int64_t o = o0 + std::min(j, count - 1), offset = 0;
        for (int axis = 3; axis >= 0; --axis) {
          const auto k = static_cast<std::size_t>(axis);
          offset += o % od[k] * xs[k];
          o /= od[k];
        }
        base[j] = offset;
      }
      for (std::int64_t r0 = 0; r0 < extent[0]; ++r0)
        for (std::int64_t r1 = 0; r1 < extent[1]; ++r1)
          for (std::int64_t r2 = 0; r2 < extent[2]; ++r2) {
            const std::int64_t off = r0 * xs[0] + r1 * xs[1] + r2 * xs[2];
            for (std::int64_t r3 = 0; r3 < extent[3]; ++r3)
              for (std::int64_t j = 0; j < kChains; ++j)
                acc[j] += p[base[j] + off + r3 * xs[3]];
          }
      for (std::int64_t j = 0; j < count; ++j)
        r[static_cast<std::size_t>(o0 + j)] = static_cast<float>(acc[j]);
    }
  };
  if (x.numel() < kParallelElements || groups == 1)
    sum_groups(0, groups);
  else
    parallel_for(groups,
                 [&](int, std::int64_t first, std::int64_t last) { sum_groups(first, last); });
  *out_dims = od;
  return r;
}

}  // namespace

// --- broadcasting -------------------------------------------------------------------------------

Shape broadcast_shape(const Shape& a, const Shape& b, const char* op) {
  const int rank = std::max(a.rank(), b.rank());
  std::array<std::int64_t, Shape::kMaxRank> dims{};
  for (int i = 0; i < rank; ++i) {
    const std::int64_t da = i < rank - a.rank() ? 1 : a[i - (rank - a.rank())];
    const std::int64_t db = i < rank - b.rank() ? 1 : b[i - (rank - b.rank())];
    if (da != db && da != 1 && db != 1) {
      throw std::invalid_argument(std::string(op) + ": shapes " + a.str() + " and " + b.str() +
                                  " do not broadcast (dimension " + std::to_string(i) + ": " +
                                  std::to_string(da) + " vs " + std::to_string(db) + ")");
    }
    dims[static_cast<std::size_t>(i)] = std::max(da, db);
  }
  return Shape(dims.data(), rank);
}

Tensor broadcast_to(const Tensor& x, const Shape& shape) {
  require_defined(x, "broadcast_to", "x");
  if (x.shape() == shape)
    return x;
  if (broadcast_shape(x.shape(), shape, "broadcast_to") != shape) {
    throw std::invalid_argument("broadcast_to: shape " + x.shape().str() +
                                " cannot be stretched to " + shape.str());
  }
  const Tensor zero = Tensor::scalar(0.0f);
  Buffer r = broadcast_apply(x, zero, shape, [](float v, float) { return v; });
  const Shape from = x.shape();
  return record(shape, std::move(r), {x}, "broadcast_to",
                [from](const Grads&, const Tensor& g) { return Grads{sum_to(g, from)}; });
}

Tensor sum_to(const Tensor& x, const Shape& shape) {
  require_defined(x, "sum_to", "x");
  if (x.shape() == shape)
    return x;
  if (broadcast_shape(shape, x.shape(), "sum_to") != x.shape()) {
    throw std::invalid_argument("sum_to: shape " + x.shape().str() + " is not a broadcast of " +
                                shape.str());
  }
  const Dims4 xd = align4(x.shape());
  const Dims4 td = align4(shape);
  std::array<bool, 4> reduce{};
  for (std::size_t i = 0; i < 4; ++i)
    reduce[i] = td[i] == 1 && xd[i] != 1;
  Dims4 od{};
  Buffer r = reduce_sum4(x, reduce, &od);
  const Shape from = x.shape();
  return record(shape, std::move(r), {x}, "sum_to",
                [from](const Grads&, const Tensor& g) { return Grads{broadcast_to(g, from)}; });
}

// --- elementwise binary -------------------------------------------------------------------------

Tensor add(const Tensor& a, const Tensor& b) {
  require_defined(a, "add", "a");
  require_defined(b, "add", "b");
  const Shape out = broadcast_shape(a.shape(), b.shape(), "add");
  return record(out, broadcast_apply(a, b, out, [](float x, float y) { return x + y; }), {a, b},
                "add", [](const Grads& in, const Tensor& g) {
                  Grads r(2);
                  if (input_grad_wanted(in[0]))
                    r[0] = sum_to(g, in[0].shape());
                  if (input_grad_wanted(in[1]))
                    r[1] = sum_to(g, in[1].shape());
                  return r;
                });
}

Tensor sub(const Tensor& a, const Tensor& b) {
  require_defined(a, "sub", "a");
  require_defined(b, "sub", "b");
  const Shape out = broadcast_shape(a.shape(), b.shape(), "sub");
  return record(out, broadcast_apply(a, b, out, [](float x, float y) { return x - y; }), {a, b},
                "sub", [](const Grads& in, const Tensor& g) {
                  Grads r(2);
                  if (input_grad_wanted(in[0]))
                    r[0] = sum_to(g, in[0].shape());
                  if (input_grad_wanted(in[1]))
                    r[1] = sum_to(neg(g), in[1].shape());
                  return r;
                });
}

Tensor mul(const Tensor& a, const Tensor& b) {
  require_defined(a, "mul", "a");
  require_defined(b, "mul", "b");
  const Shape out = broadcast_shape(a.shape(), b.shape(), "mul");
  return record(out, broadcast_apply(a, b, out, [](float x, float y) { return x * y; }), {a, b},
                "mul", [](const Grads& in, const Tensor& g) {
                  Grads r(2);
                  if (input_grad_wanted(in[0]))
                    r[0] = sum_to(mul(g, in[1]), in[0].shape());
                  if (input_grad_wanted(in[1]))
                    r[1] = sum_to(mul(g, in[0]), in[1].shape());
                  return r;
                });
}

Tensor div(const Tensor& a, const Tensor& b) {
  require_defined(a, "div", "a");
  require_defined(b, "div", "b");
  const Shape out = broadcast_shape(a.shape(), b.shape(), "div");
  return record(out, broadcast_apply(a, b, out, [](float x, float y) { return x / y; }), {a, b},
                "div", [](const Grads& in, const Tensor& g) {
                  Grads r(2);
                  if (input_grad_wanted(in[0]))
                    r[0] = sum_to(div(g, in[1]), in[0].shape());
                  if (input_grad_wanted(in[1])) {
                    // d(a/b)/db = -a / b^2
                    r[1] = sum_to(neg(div(mul(g, in[0]), square(in[1]))), in[1].shape());
                  }
                  return r;
                });
}

Tensor add_scalar(const Tensor& x, float c) {
  return unary(
      x, "add_scalar", [c](float v) { return v + c; },
      [](const Grads&, const Tensor& g) { return Grads{g}; });
}

Tensor mul_scalar(const Tensor& x, float c) {
  return unary(
      x, "mul_scalar", [c](float v) { return v * c; },
      [c](const Grads&, const Tensor& g) { return Grads{mul_scalar(g, c)}; });
}

// --- elementwise unary --------------------------------------------------------------------------

Tensor neg(const Tensor& x) {
  return unary(
      x, "neg", [](float v) { return -v; },
      [](const Grads&, const Tensor& g) { return Grads{neg(g)}; });
}

Tensor exp(const Tensor& x) {
  return unary(
      x, "exp", [](float v) { return std::exp(v); },
      [](const Grads& in, const Tensor& g) { return Grads{mul(g, exp(in[0]))}; });
}

Tensor log(const Tensor& x) {
  return unary(
      x, "log", [](float v) { return std::log(v); },
      [](const Grads& in, const Tensor& g) { return Grads{div(g, in[0])}; });
}

Tensor log1p(const Tensor& x) {
  return unary(
      x, "log1p", [](float v) { return std::log1p(v); },
      [](const Grads& in, const Tensor& g) { return Grads{div(g, add_scalar(in[0], 1.0f))}; });
}

Tensor sqrt(const Tensor& x) {
  return unary(
      x, "sqrt", [](float v) { return std::sqrt(v); },
      [](const Grads& in, const Tensor& g) {
        return Grads{div(mul_scalar(g, 0.5f), sqrt(in[0]))};
      });
}

Tensor square(const Tensor& x) {
  return unary(
      x, "square", [](float v) { return v * v; },
      [](const Grads& in, const Tensor& g) { return Grads{mul(g, mul_scalar(in[0], 2.0f))}; });
}

Tensor abs(const Tensor& x) {
  return unary(
      x, "abs", [](float v) { return std::abs(v); },
      [](const Grads& in, const Tensor& g) {
        // sign(x) is piecewise constant: a constant tensor, so second derivatives are 0
        const Tensor sign = constant_map(
            in[0], [](float v) { return v > 0.0f ? 1.0f : (v < 0.0f ? -1.0f : 0.0f); });
        return Grads{mul(g, sign)};
      });
}

Tensor relu(const Tensor& x) {
  return unary(
      x, "relu", [](float v) { return v > 0.0f ? v : 0.0f; },
      [](const Grads& in, const Tensor& g) {
        if (!grad_mode_enabled())
          return Grads{masked_by_positive(g, in[0])};
        // create_graph: the step is a constant, so the second derivative is zero
        const Tensor step = constant_map(in[0], [](float v) { return v > 0.0f ? 1.0f : 0.0f; });
        return Grads{mul(g, step)};
      });
}

namespace {
float sigmoid_of(float v) {
  if (v >= 0.0f)
    return 1.0f / (1.0f + std::exp(-v));
  const float e = std::exp(v);
  return e / (1.0f + e);
}

// The sigmoid node of x whose values `s` are already computed: its backward reads s instead
// of computing the exponentials again. The node shares s (not the output tensor, which would
// make a reference cycle through the node); the output holds a copy. Unlike other nodes it
// does not see a write into x between the forward and the backward, which tensor.hpp rules
// out (write only between steps).
Tensor sigmoid_node(const Tensor& x, std::shared_ptr<const Buffer> s) {
  return record(x.shape(), Buffer(s->begin(), s->end()), {x}, "sigmoid",
                [s](const Grads& in, const Tensor& g) {
                  // s' = s (1 - s)
                  if (!grad_mode_enabled()) {
                    // in one pass, with the operations (and so the bits) of the graph below:
                    // g * (s * ((-s) + 1))
                    Buffer r(s->size());
                    float* pr = r.data();
                    const float* pg = g.data();
                    const float* ps = s->data();
                    elementwise_for(static_cast<std::int64_t>(s->size()),
                                    [&](std::int64_t begin, std::int64_t end) {
                                      for (std::int64_t i = begin; i < end; ++i)
                                        pr[i] = pg[i] * (ps[i] * (-ps[i] + 1.0f));
                                    });
                    return Grads{Tensor(in[0].shape(), std::move(r))};
                  }
                  // create_graph: s as a node of x again (sharing the same values), so that
                  // s' has its own derivative
                  const Tensor sx = sigmoid_node(in[0], s);
                  return Grads{mul(g, mul(sx, add_scalar(neg(sx), 1.0f)))};
                });
}
}  // namespace

Tensor sigmoid(const Tensor& x) {
  require_defined(x, "sigmoid", "x");
  Buffer r = map_values(x, sigmoid_of);
  if (!needs_graph({x}))
    return Tensor(x.shape(), std::move(r));
  return sigmoid_node(x, std::make_shared<const Buffer>(std::move(r)));
}

// --- shape ----------------------------------------------------------------------------------

Tensor reshape(const Tensor& x, const Shape& shape) {
  require_defined(x, "reshape", "x");
  if (shape.numel() != x.numel()) {
    throw std::invalid_argument("reshape: cannot view shape " + x.shape().str() + " (" +
                                std::to_string(x.numel()) + " elements) as " + shape.str() + " (" +
                                std::to_string(shape.numel()) + ")");
  }
  const Shape from = x.shape();
  std::shared_ptr<Node> node;
  if (needs_graph({x})) {
    node = std::make_shared<FnNode>(
        "reshape", [from](const Grads&, const Tensor& g) { return Grads{reshape(g, from)}; });
  }
  return share_storage(x, shape, std::move(node));
}

Tensor flatten(const Tensor& x) {
  require_defined(x, "flatten", "x");
  if (x.rank() < 1)
    throw std::invalid_argument("flatten: x is a scalar; expected rank >= 1");
  return reshape(x, Shape{x.shape()[0], x.shape()[0] == 0 ? 0 : x.numel() / x.shape()[0]});
}

Tensor concat(const std::vector<Tensor>& xs, int axis) {
  if (xs.empty())
    throw std::invalid_argument("concat: no tensors");
  for (const Tensor& t : xs)
    require_defined(t, "concat", "an input");
  const Shape& s0 = xs[0].shape();
  const int ax = normalize_axis(axis, s0.rank(), "concat");
  std::vector<std::int64_t> dims = s0.dims();
  dims[static_cast<std::size_t>(ax)] = 0;
  for (const Tensor& t : xs) {
    bool ok = t.rank() == s0.rank();
    for (int i = 0; ok && i < s0.rank(); ++i)
      ok = i == ax || t.shape()[i] == s0[i];
    if (!ok) {
      throw std::invalid_argument("concat: shapes " + s0.str() + " and " + t.shape().str() +
                                  " differ outside axis " + std::to_string(ax));
    }
    dims[static_cast<std::size_t>(ax)] += t.shape()[ax];
  }
  const Shape out(dims);
  // outer: product of dims before the axis; each input contributes a run per outer index
  std::int64_t outer = 1;
  for (int i = 0; i < ax; ++i)
    outer *= s0[i];
  std::int64_t inner = 1;
  for (int i = ax + 1; i < s0.rank(); ++i)
    inner *= s0[i];
  Buffer r(static_cast<std::size_t>(out.numel()));
  std::size_t k = 0;
  for (std::int64_t o = 0; o < outer; ++o) {
    for (const Tensor& t : xs) {
      const std::int64_t run = t.shape()[ax] * inner;
      std::copy_n(t.data() + o * run, run, r.begin() + static_cast<std::ptrdiff_t>(k));
      k += static_cast<std::size_t>(run);
    }
  }
  std::vector<std::int64_t> sizes;
  for (const Tensor& t : xs)
    sizes.push_back(t.shape()[ax]);
  return record(out, std::move(r), xs, "concat", [ax, sizes](const Grads&, const Tensor& g) {
    Grads parts;
    std::int64_t begin = 0;
    for (std::int64_t size : sizes) {
      parts.push_back(slice(g, ax, begin, begin + size));
      begin += size;
    }
    return parts;
  });
}

Tensor slice(const Tensor& x, int axis, std::int64_t begin, std::int64_t end) {
  require_defined(x, "slice", "x");
  const int ax = normalize_axis(axis, x.rank(), "slice");
  const std::int64_t size = x.shape()[ax];
  if (begin < 0 || end > size || begin > end) {
    throw std::invalid_argument("slice: [" + std::to_string(begin) + ", " + std::to_string(end) +
                                ") is not inside axis " + std::to_string(ax) + " of shape " +
                                x.shape().str());
  }
  std::vector<std::int64_t> dims = x.shape().dims();
  dims[static_cast<std::size_t>(ax)] = end - begin;
  const Shape out(dims);
  std::int64_t outer = 1;
  for (int i = 0; i < ax; ++i)
    outer *= x.shape()[i];
  std::int64_t inner = 1;
  for (int i = ax + 1; i < x.rank(); ++i)
    inner *= x.shape()[i];
  Buffer r(static_cast<std::size_t>(out.numel()));
  const std::int64_t run = (end - begin) * inner;
  for (std::int64_t o = 0; o < outer; ++o) {
    std::copy_n(x.data() + o * size * inner + begin * inner, run,
                r.begin() + static_cast<std::ptrdiff_t>(o * run));
  }
  return record(out, std::move(r), {x}, "slice",
                [ax, begin, end, size](const Grads& in, const Tensor& g) {
                  // the adjoint pads g with zeros back to the input's extent
                  std::vector<Tensor> parts;
                  std::vector<std::int64_t> pad = in[0].shape().dims();
                  if (begin > 0) {
                    pad[static_cast<std::size_t>(ax)] = begin;
                    parts.push_back(Tensor::zeros(Shape(pad)));
                  }
                  parts.push_back(g);
                  if (end < size) {
                    pad[static_cast<std::size_t>(ax)] = size - end;
                    parts.push_back(Tensor::zeros(Shape(pad)));
                  }
                  return Grads{parts.size() == 1 ? g : concat(parts, ax)};
                });
}

namespace {

// r [n, m] = p [m, n] transposed. In 8x8 tiles (eight row loads, shuffles, eight stores) a
// band of 16 columns of p at a time: r's rows are m floats apart, and a power-of-two m puts
// them in a few cache sets, so a band keeps the rows being written few enough to stay in
// L1 (a 256 x 256 matrix: 10 us instead of 240 for the plain loop, which wrote one element
// of each of r's rows in turn). A pure copy: the values are the plain loop's.
void transpose_into(const float* p, float* r, std::int64_t m, std::int64_t n) {
  constexpr std::int64_t kBand = 16;
  std::int64_t m8 = 0, n8 = 0;
#ifdef __AVX__
  m8 = m & ~std::int64_t{7};
  n8 = n & ~std::int64_t{7};
  for (std::int64_t band = 0; band < n8; band += kBand) {
    const std::int64_t band_end = std::min(band + kBand, n8);
    for (std::int64_t i = 0; i < m8; i += 8) {
      for (std::int64_t j = band; j < band_end; j += 8) {
        const float* s = p + i * n + j;
        const __m256 r0 = _mm256_loadu_ps(s), r1 = _mm256_loadu_ps(s + n),
                     r2 = _mm256_loadu_ps(s + 2 * n), r3 = _mm256_loadu_ps(s + 3 * n),
                     r4 = _mm256_loadu_ps(s + 4 * n), r5 = _mm256_loadu_ps(s + 5 * n),
                     r6 = _mm256_loadu_ps(s + 6 * n), r7 = _mm256_loadu_ps(s + 7 * n);
        // pairs of rows interleaved, then pairs of pairs: each 128-bit half holds a 4 x 4
        // tile transposed; the last step pairs the halves
        const __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpackhi_ps(r0, r1),
                     t2 = _mm256_unpacklo_ps(r2, r3), t3 = _mm256_unpackhi_ps(r2, r3),
                     t4 = _mm256_unpacklo_ps(r4, r5), t5 = _mm256_unpackhi_ps(r4, r5),
                     t6 = _mm256_unpacklo_ps(r6, r7), t7 = _mm256_unpackhi_ps(r6, r7);
        const __m256 u0 = _mm256_shuffle_ps(t0, t2, 0x44), u1 = _mm256_shuffle_ps(t0, t2, 0xEE),
                     u2 = _mm256_shuffle_ps(t1, t3, 0x44), u3 = _mm256_shuffle_ps(t1, t3, 0xEE),
                     u4 = _mm256_shuffle_ps(t4, t6, 0x44), u5 = _mm256_shuffle_ps(t4, t6, 0xEE),
                     u6 = _mm256_shuffle_ps(t5, t7, 0x44), u7 = _mm256_shuffle_ps(t5, t7, 0xEE);
        float* d = r + j * m + i;
        _mm256_storeu_ps(d, _mm256_permute2f128_ps(u0, u4, 0x20));
        _mm256_storeu_ps(d + m, _mm256_permute2f128_ps(u1, u5, 0x20));
        _mm256_storeu_ps(d + 2 * m, _mm256_permute2f128_ps(u2, u6, 0x20));
        _mm256_storeu_ps(d + 3 * m, _mm256_permute2f128_ps(u3, u7, 0x20));
        _mm256_storeu_ps(d + 4 * m, _mm256_permute2f128_ps(u0, u4, 0x31));
        _mm256_storeu_ps(d + 5 * m, _mm256_permute2f128_ps(u1, u5, 0x31));
        _mm256_storeu_ps(d + 6 * m, _mm256_permute2f128_ps(u2, u6, 0x31));
        _mm256_storeu_ps(d + 7 * m, _mm256_permute2f128_ps(u3, u7, 0x31));
      }
    }
  }
#endif
  // what the tiles left: the last columns of the tiled rows, and every column of the rest,
  // in bands as well
  for (std::int64_t band = 0; band < n; band += kBand) {
    const std::int64_t band_end = std::min(band + kBand, n);
    for (std::int64_t i = 0; i < m; ++i)
      for (std::int64_t j = std::max(band, i < m8 ? n8 : 0); j < band_end; ++j)
        r[j * m + i] = p[i * n + j];
  }
}

}  // namespace

Tensor transpose(const Tensor& x) {
  require_defined(x, "transpose", "x");
  if (x.rank() != 2) {
    throw std::invalid_argument("transpose: shape " + x.shape().str() + "; expected rank 2");
  }
  const std::int64_t m = x.shape()[0], n = x.shape()[1];
  Buffer r(static_cast<std::size_t>(m * n));
  transpose_into(x.data(), r.data(), m, n);
  return record(Shape{n, m}, std::move(r), {x}, "transpose",
                [](const Grads&, const Tensor& g) { return Grads{transpose(g)}; });
}

// --- reductions -----------------------------------------------------------------------------

Tensor sum(const Tensor& x) {
  require_defined(x, "sum", "x");
  std::vector<int> axes(static_cast<std::size_t>(x.rank()));
  for (int i = 0; i < x.rank(); ++i)
    axes[static_cast<std::size_t>(i)] = i;
  return sum(x, axes, false);
}

Tensor sum(const Tensor& x, const std::vector<int>& axes, bool keepdim) {
  require_defined(x, "sum", "x");
  const int rank = x.rank();
  std::array<bool, 4> reduce{};
  std::vector<std::int64_t> kept_dims = x.shape().dims(), out_dims;
  for (int axis : axes) {
    const int a = normalize_axis(axis, rank, "sum");
    if (reduce[static_cast<std::size_t>(4 - rank + a)]) {
      throw std::invalid_argument("sum: axis " + std::to_string(axis) + " is given twice");
    }
    reduce[static_cast<std::size_t>(4 - rank + a)] = true;
    kept_dims[static_cast<std::size_t>(a)] = 1;
  }
  for (int i = 0; i < rank; ++i) {
    if (!reduce[static_cast<std::size_t>(4 - rank + i)])
      out_dims.push_back(x.shape()[i]);
  }
  Dims4 od{};
  Buffer r = reduce_sum4(x, reduce, &od);
  const Shape kept(kept_dims);
  const Shape out = keepdim ? kept : Shape(out_dims);
  const Shape from = x.shape();
  return record(out, std::move(r), {x}, "sum", [kept, from](const Grads&, const Tensor& g) {
    return Grads{broadcast_to(reshape(g, kept), from)};
  });
}

Tensor mean(const Tensor& x) {
  require_defined(x, "mean", "x");
  return mul_scalar(sum(x), 1.0f / static_cast<float>(x.numel()));
}

Tensor mean(const Tensor& x, const std::vector<int>& axes, bool keepdim) {
  require_defined(x, "mean", "x");
  std::int64_t count = 1;
  for (int axis : axes)
    count *= x.shape()[normalize_axis(axis, x.rank(), "mean")];
  return mul_scalar(sum(x, axes, keepdim), 1.0f / static_cast<float>(count));
}

// --- linear algebra -------------------------------------------------------------------------

Tensor matmul(const Tensor& a, const Tensor& b) {
  require_defined(a, "matmul", "a");
  require_defined(b, "matmul", "b");
  if (a.rank() != 2 || b.rank() != 2 || a.shape()[1] != b.shape()[0]) {
    throw std::invalid_argument("matmul: shapes " + a.shape().str() + " and " + b.shape().str() +
                                "; expected [m, k] and [k, n]");
  }
  const std::int64_t m = a.shape()[0], k = a.shape()[1], n = b.shape()[1];
  Buffer r(static_cast<std::size_t>(m * n));
  add_flops(static_cast<std::uint64_t>(2 * m * k * n));
  gemm(a.data(), b.data(), r.data(), m, k, n);
  return record(Shape{m, n}, std::move(r), {a, b}, "matmul", [](const Grads& in, const Tensor& g) {
    Grads grads(2);
    if (input_grad_wanted(in[0]))
      grads[0] = matmul(g, transpose(in[1]));
    if (input_grad_wanted(in[1]))
      grads[1] = matmul(transpose(in[0]), g);
    return grads;
  });
}

// --- losses ---------------------------------------------------------------------------------

Tensor mse_loss(const Tensor& prediction, const Tensor& target) {
  require_defined(prediction, "mse_loss", "prediction");
  require_defined(target, "mse_loss", "target");
  if (prediction.shape() != target.shape()) {
    throw std::invalid_argument("mse_loss: prediction " + prediction.shape().str() +
                                " and target " + target.shape().str() + " differ");
  }
  return mean(square(sub(prediction, target)));
}

namespace {
void check_bce_inputs(const Tensor& logits, const Tensor& targets, const char* op) {
  require_defined(logits, op, "logits");
  require_defined(targets, op, "targets");
  if (logits.shape() != targets.shape()) {
    throw std::invalid_argument(std::string(op) + ": logits " + logits.shape().str() +
                                " and targets " + targets.shape().str() + " differ");
  }
}
}  // namespace

Tensor bce_with_logits_elementwise(const Tensor& logits, const Tensor& targets) {
  check_bce_inputs(logits, targets, "bce_with_logits_elementwise");
  const float* z = logits.data();
  const float* y = targets.data();
  Buffer out(static_cast<std::size_t>(logits.numel()));
  for (std::int64_t i = 0; i < logits.numel(); ++i) {
    const double zi = z[i];
    out[static_cast<std::size_t>(i)] =
        static_cast<float>(std::max(zi, 0.0) - zi * y[i] + std::log1p(std::exp(-std::abs(zi))));
  }
  // as bce_with_logits, per element: sigmoid(z) - y and -z
  return record(logits.shape(), std::move(out), {logits, targets}, "bce_with_logits_elementwise",
                [](const Grads& in, const Tensor& g) {
                  Grads r(2);
                  if (in[0].requires_grad())
                    r[0] = mul(sub(sigmoid(in[0]), in[1]), g);
                  if (in[1].requires_grad())
                    r[1] = mul(neg(in[0]), g);
                  return r;
                });
}

Tensor bce_with_logits(const Tensor& logits, const Tensor& targets) {
  check_bce_inputs(logits, targets, "bce_with_logits");
  // value: mean(max(z, 0) - z y + log1p(exp(-|z|))), in double
  const float* z = logits.data();
  const float* y = targets.data();
  double total = 0;
  for (std::int64_t i = 0; i < logits.numel(); ++i) {
    const double zi = z[i];
    total += std::max(zi, 0.0) - zi * y[i] + std::log1p(std::exp(-std::abs(zi)));
  }
  const float n = static_cast<float>(logits.numel());
  // gradient (sigmoid(z) - y) / N and -z / N, as PyTorch, also at z == 0 (where the
  // composed form's relu' and abs' would both be 0); written with differentiable ops
  return record(Shape{}, Buffer(1, static_cast<float>(total / n)), {logits, targets},
                "bce_with_logits", [n](const Grads& in, const Tensor& g) {
                  Grads r(2);
                  if (in[0].requires_grad()) {
                    r[0] = mul(mul_scalar(sub(sigmoid(in[0]), in[1]), 1.0f / n), g);
                  }
                  if (in[1].requires_grad())
                    r[1] = mul(mul_scalar(neg(in[0]), 1.0f / n), g);
                  return r;
                });
}

}  // namespace ropes::nn
