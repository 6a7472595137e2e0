#include "ropes_nn/tensor.hpp"

#include <sstream>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

#include "ropes_nn/ops.hpp"
#include "tensor_impl.hpp"

namespace ropes::nn {

// --- Shape ----------------------------------------------------------------------------------

Shape::Shape(std::initializer_list<std::int64_t> dims) {
  assign(dims.begin(), dims.size());
}

Shape::Shape(const std::vector<std::int64_t>& dims) {
  assign(dims.data(), dims.size());
}

Shape::Shape(const std::int64_t* dims, int rank) {
  if (rank < 0)
    throw std::invalid_argument("Shape: rank " + std::to_string(rank) + "; expected 0 to 4");
  assign(dims, static_cast<std::size_t>(rank));
}

void Shape::assign(const std::int64_t* dims, std::size_t rank) {
  if (rank > static_cast<std::size_t>(kMaxRank)) {
    throw std::invalid_argument("Shape: rank " + std::to_string(rank) +
                                " is not supported; expected at most 4");
  }
  rank_ = static_cast<int>(rank);
  for (int i = 0; i < rank_; ++i) {
    if (dims[i] < 0) {
      throw std::invalid_argument("Shape: dimension " + std::to_string(i) + " is " +
                                  std::to_string(dims[i]) + "; expected >= 0");
    }
    dims_[static_cast<std::size_t>(i)] = dims[i];
  }
}

std::int64_t Shape::numel() const {
  std::int64_t n = 1;
  for (int i = 0; i < rank_; ++i)
    n *= dims_[static_cast<std::size_t>(i)];
  return n;
}

std::string Shape::str() const {
  std::ostringstream s;
  s << '[';
  for (int i = 0; i < rank_; ++i)
    s << (i ? ", " : "") << dims_[static_cast<std::size_t>(i)];
  s << ']';
  return s.str();
}

bool Shape::operator==(const Shape& other) const {
  if (rank_ != other.rank_)
    return false;
  for (int i = 0; i < rank_; ++i) {
    if (dims_[static_cast<std::size_t>(i)] != other.dims_[static_cast<std::size_t>(i)]) {
      return false;
    }
  }
  return true;
}

// --- grad mode ------------------------------------------------------------------------------

namespace {
thread_local bool g_grad_mode = true;

// tensor handles and their storage's control blocks come from the buffer pool too, so that
// a warm forward pass without grad mode allocates nothing from the system
std::shared_ptr<TensorImpl> new_impl() {
  return std::allocate_shared<TensorImpl>(PoolAllocator<TensorImpl>());
}

const TensorImpl& checked(const std::shared_ptr<TensorImpl>& impl, const char* what) {
  if (!impl)
    throw std::invalid_argument(std::string("Tensor::") + what + ": undefined tensor");
  return *impl;
}
}  // namespace

bool grad_mode_enabled() {
  return g_grad_mode;
}

GradModeGuard::GradModeGuard(bool enabled) : previous_(g_grad_mode) {
  g_grad_mode = enabled;
}
GradModeGuard::~GradModeGuard() {
  g_grad_mode = previous_;
}

// --- Tensor ---------------------------------------------------------------------------------

Tensor::Tensor(const Shape& shape, const std::vector<float>& values, bool requires_grad)
    : Tensor(shape, Buffer(values.begin(), values.end()), requires_grad) {}

Tensor::Tensor(const Shape& shape, Buffer values, bool requires_grad) {
  if (static_cast<std::int64_t>(values.size()) != shape.numel()) {
    throw std::invalid_argument("Tensor: " + std::to_string(values.size()) + " values for shape " +
                                shape.str() + "; expected " + std::to_string(shape.numel()));
  }
  impl_ = new_impl();
  impl_->shape = shape;
  impl_->storage = std::allocate_shared<Buffer>(PoolAllocator<Buffer>(), std::move(values));
  impl_->requires_grad = requires_grad;
}

Tensor Tensor::zeros(const Shape& shape, bool requires_grad) {
  return full(shape, 0.0f, requires_grad);
}
Tensor Tensor::ones(const Shape& shape, bool requires_grad) {
  return full(shape, 1.0f, requires_grad);
}
Tensor Tensor::full(const Shape& shape, float value, bool requires_grad) {
  return Tensor(shape, Buffer(static_cast<std::size_t>(shape.numel()), value), requires_grad);
}
Tensor Tensor::scalar(float value, bool requires_grad) {
  return Tensor(Shape{}, Buffer(1, value), requires_grad);
}

const Shape& Tensor::shape() const {
  return checked(impl_, "shape").shape;
}
const float* Tensor::data() const {
  return checked(impl_, "data").storage->data();
}
float* Tensor::mutable_data() {
  return checked(impl_, "mutable_data").storage->data();
}
std::vector<float> Tensor::to_vector() const {
  const TensorImpl& impl = checked(impl_, "to_vector");
  return std::vector<float>(impl.storage->begin(), impl.storage->end());
}

float Tensor::item() const {
  if (numel() != 1) {
    throw std::invalid_argument("Tensor::item: shape " + shape().str() + " has " +
                                std::to_string(numel()) + " elements; expected 1");
  }
  return data()[0];
}

bool Tensor::requires_grad() const {
  return impl_ && impl_->requires_grad;
}
bool Tensor::is_leaf() const {
  return checked(impl_, "is_leaf").grad_fn == nullptr;
}
const std::shared_ptr<Node>& Tensor::grad_fn() const {
  return checked(impl_, "grad_fn").grad_fn;
}

Tensor& Tensor::set_requires_grad(bool value) {
  if (checked(impl_, "set_requires_grad").grad_fn != nullptr) {
    throw std::invalid_argument(
        std::string("Tensor::set_requires_grad: the tensor was produced by ") +
        impl_->grad_fn->name() + "; only leaves can be marked");
  }
  impl_->requires_grad = value;
  return *this;
}

Tensor Tensor::grad() const {
  return checked(impl_, "grad").grad;
}
void Tensor::zero_grad() {
  checked(impl_, "zero_grad");
  impl_->grad = Tensor();
}

Tensor Tensor::detach() const {
  const TensorImpl& impl = checked(impl_, "detach");
  return Tensor(impl.shape, *impl.storage);
}

void accumulate_leaf_grad(const Tensor& leaf, const Tensor& g) {
  GradModeGuard no_grad(false);
  leaf.impl_->grad = leaf.impl_->grad.defined() ? add(leaf.impl_->grad, g) : g.detach();
}

void Tensor::backward(const Tensor& grad_output) const {
  checked(impl_, "backward");
  // collect the leaves that need a gradient
  std::vector<Tensor> leaves;
  std::unordered_set<const TensorImpl*> seen;
  std::vector<Tensor> stack = {*this};
  while (!stack.empty()) {
    Tensor t = stack.back();
    stack.pop_back();
    if (!t.requires_grad() || !seen.insert(t.id()).second)
      continue;
    if (t.is_leaf()) {
      leaves.push_back(t);
    } else {
      for (const Tensor& in : t.grad_fn()->inputs)
        stack.push_back(in);
    }
  }
  if (leaves.empty()) {
    throw std::invalid_argument(
        "Tensor::backward: the tensor does not depend on any tensor "
        "that requires grad");
  }
  const std::vector<Tensor> grads =
      nn::grad({*this}, leaves,
               grad_output.defined() ? std::vector<Tensor>{grad_output} : std::vector<Tensor>{});
  for (std::size_t i = 0; i < leaves.size(); ++i)
    accumulate_leaf_grad(leaves[i], grads[i]);
}

Tensor Tensor::reshape(const Shape& shape) const {
  return nn::reshape(*this, shape);
}

Tensor share_storage(const Tensor& source, const Shape& shape, std::shared_ptr<Node> node) {
  Tensor t;
  t.impl_ = new_impl();
  t.impl_->shape = shape;
  t.impl_->storage = source.impl_->storage;
  if (grad_mode_enabled() && source.requires_grad()) {
    node->inputs = {source};
    t.impl_->requires_grad = true;
    t.impl_->grad_fn = std::move(node);
  }
  return t;
}

Tensor make_op_result(const Shape& shape, Buffer values, std::shared_ptr<Node> node,
                      std::vector<Tensor> inputs) {
  Tensor t(shape, std::move(values));
  if (!grad_mode_enabled())
    return t;
  for (const Tensor& in : inputs) {
    if (in.requires_grad()) {
      node->inputs = std::move(inputs);
      t.impl_->requires_grad = true;
      t.impl_->grad_fn = std::move(node);
      break;
    }
  }
  return t;
}

// --- the reverse sweep ----------------------------------------------------------------------

namespace {

// the tensors on a path to what the innermost running grad() asks for (null outside grad());
// a node's backward that calls grad() itself (group norm's) nests a call of its own
thread_local const std::unordered_set<const TensorImpl*>* t_needed = nullptr;

class NeededGuard {
 public:
  explicit NeededGuard(const std::unordered_set<const TensorImpl*>* needed) : previous_(t_needed) {
    t_needed = needed;
  }
  ~NeededGuard() { t_needed = previous_; }
  NeededGuard(const NeededGuard&) = delete;
  NeededGuard& operator=(const NeededGuard&) = delete;

 private:
  const std::unordered_set<const TensorImpl*>* previous_;
};

std::vector<Tensor> grad_impl(const std::vector<Tensor>& outputs, const std::vector<Tensor>& inputs,
                              const std::vector<Tensor>& grad_outputs, bool create_graph,
                              bool allow_unused, bool stop_at_inputs) {
  if (!grad_outputs.empty() && grad_outputs.size() != outputs.size()) {
    throw std::invalid_argument("grad: " + std::to_string(grad_outputs.size()) +
                                " grad_outputs for " + std::to_string(outputs.size()) +
                                " outputs; expected one each, or none");
  }
  GradModeGuard mode(create_graph);

  // seed the output gradients
  std::unordered_map<const TensorImpl*, Tensor> grads;
  for (std::size_t k = 0; k < outputs.size(); ++k) {
    const Tensor& out = outputs[k];
    Tensor seed;
    if (grad_outputs.empty()) {
      if (out.numel() != 1) {
        throw std::invalid_argument("grad: output " + std::to_string(k) + " has shape " +
                                    out.shape().str() +
                                    "; give grad_outputs for outputs that "
                                    "are not scalars");
      }
      seed = Tensor::ones(out.shape());
    } else {
      seed = grad_outputs[k];
      if (seed.shape() != out.shape()) {
        throw std::invalid_argument("grad: grad_outputs[" + std::to_string(k) + "] has shape " +
                                    seed.shape().str() + " but output " + std::to_string(k) +
                                    " has shape " + out.shape().str());
      }
    }
    auto [it, fresh] = grads.emplace(out.id(), seed);
    if (!fresh)
      it->second = add(it->second, seed);
  }

  std::unordered_set<const TensorImpl*> asked;
  for (const Tensor& in : inputs)
    asked.insert(in.id());

  // topological order of the tensors that need a gradient (iterative depth-first search)
  std::vector<Tensor> order;
  std::unordered_set<const TensorImpl*> visited;
  struct Frame {
    Tensor tensor;
    std::size_t next_input;
  };
  std::vector<Frame> stack;
  for (const Tensor& out : outputs) {
    if (!out.requires_grad() || !visited.insert(out.id()).second)
      continue;
    stack.push_back({out, 0});
    while (!stack.empty()) {
      Frame& top = stack.back();
      const std::shared_ptr<Node>& node = top.tensor.grad_fn();
      const bool expand = !(stop_at_inputs && asked.count(top.tensor.id()));
      if (node && expand && top.next_input < node->inputs.size()) {
        const Tensor in = node->inputs[top.next_input++];
        if (in.requires_grad() && visited.insert(in.id()).second)
          stack.push_back({in, 0});
      } else {
        order.push_back(top.tensor);
        stack.pop_back();
      }
    }
  }

  // only tensors on a path to an asked-for input matter (and a node's backward must not run
  // for anything else: group_norm's differentiable backward calls grad() itself). `order`
  // lists every tensor after the tensors it was computed from, so one pass marks them.
  std::unordered_set<const TensorImpl*> needed;
  for (const Tensor& in : inputs)
    needed.insert(in.id());
  for (const Tensor& t : order) {
    const std::shared_ptr<Node>& node = t.grad_fn();
    if (!node || needed.count(t.id()))
      continue;
    for (const Tensor& in : node->inputs) {
      if (needed.count(in.id())) {
        needed.insert(t.id());
        break;
      }
    }
  }

  // walk from the outputs towards the inputs, pushing each gradient to the node's inputs
  const NeededGuard needed_while_walking(&needed);
  for (auto it = order.rbegin(); it != order.rend(); ++it) {
    const Tensor& t = *it;
    const std::shared_ptr<Node>& node = t.grad_fn();
    if (!node || !needed.count(t.id()) || (stop_at_inputs && asked.count(t.id())))
      continue;
    auto found = grads.find(t.id());
    if (found == grads.end())
      continue;
    const Tensor g = found->second;
    const std::vector<Tensor> input_grads = node->backward(g);
    ROPES_DEMAND(input_grads.size() == node->inputs.size(),
                 std::string(node->name()) + "::backward returned " +
                     std::to_string(input_grads.size()) + " gradients for " +
                     std::to_string(node->inputs.size()) + " inputs");
    for (std::size_t i = 0; i < node->inputs.size(); ++i) {
      const Tensor& in = node->inputs[i];
      if (!in.requires_grad() || !input_grads[i].defined() || !needed.count(in.id()))
        continue;
      auto [slot, fresh] = grads.emplace(in.id(), input_grads[i]);
      if (!fresh)
        slot->second = add(slot->second, input_grads[i]);
    }
  }

  std::vector<Tensor> result;
  result.reserve(inputs.size());
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    auto found = grads.find(inputs[i].id());
    if (found != grads.end()) {
      result.push_back(found->second);
    } else if (allow_unused) {
      result.push_back(Tensor::zeros(inputs[i].shape()));
    } else {
      throw std::invalid_argument("grad: the outputs do not depend on inputs[" + std::to_string(i) +
                                  "] (shape " + inputs[i].shape().str() +
                                  "); pass allow_unused = true to get zeros");
    }
  }
  return result;
}

}  // namespace

bool input_grad_wanted(const Tensor& input) {
  return input.requires_grad() && (t_needed == nullptr || t_needed->count(input.id()) > 0);
}

std::vector<Tensor> grad(const std::vector<Tensor>& outputs, const std::vector<Tensor>& inputs,
                         const std::vector<Tensor>& grad_outputs, bool create_graph,
                         bool allow_unused) {
  return grad_impl(outputs, inputs, grad_outputs, create_graph, allow_unused, false);
}

std::vector<Tensor> grad_stopping_at_inputs(const std::vector<Tensor>& outputs,
                                            const std::vector<Tensor>& inputs,
                                            const std::vector<Tensor>& grad_outputs,
                                            bool create_graph) {
  return grad_impl(outputs, inputs, grad_outputs, create_graph, true, true);
}

}  // namespace ropes::nn
