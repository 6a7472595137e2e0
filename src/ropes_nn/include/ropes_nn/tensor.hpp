#pragma once
/// @file tensor.hpp
/// Tensor: a float32 array of rank 0 to 4 with reverse-mode autodiff.
///
/// A Tensor is a handle: copies share the same storage and the same autodiff node. Images
/// are NCHW. A tensor that requires_grad() and was computed by an operation remembers that
/// operation (grad_fn()), so ropes::nn::grad() can walk back to the leaves. Every
/// operation's backward is written with the same differentiable operations, so gradients
/// can themselves be differentiated (grad(..., create_graph = true)).
///
/// Storage is contiguous and row-major; reshape() shares it. Operations never write into
/// their inputs.

#include <array>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

#include "ropes_nn/buffer.hpp"
#include "ropes_nn/demand.hpp"

namespace ropes::nn {

class Node;
struct TensorImpl;

/// The shape of a tensor: rank 0 (a scalar) to 4.
class Shape {
 public:
  static constexpr int kMaxRank = 4;

  Shape() = default;  // rank 0: a scalar
  /// Throws std::invalid_argument for rank > 4 or a negative dimension.
  Shape(std::initializer_list<std::int64_t> dims);
  explicit Shape(const std::vector<std::int64_t>& dims);
  /// The first `rank` entries of `dims` (no allocation, unlike the vector form).
  Shape(const std::int64_t* dims, int rank);

  int rank() const { return rank_; }
  /// The size of dimension `axis`, 0 <= axis < rank() (ROPES_DEMAND: an axis outside the
  /// rank is a bug in the caller's shape logic, never read past the dimensions).
  std::int64_t operator[](int axis) const {
    ROPES_DEMAND(axis >= 0 && axis < rank_, "Shape" + str() + "[" + std::to_string(axis) +
                                                "]: axis outside the rank " +
                                                std::to_string(rank_));
    return dims_[static_cast<std::size_t>(axis)];
  }
  /// Product of the dimensions (1 for a scalar).
  std::int64_t numel() const;
  std::vector<std::int64_t> dims() const { return {dims_.begin(), dims_.begin() + rank_}; }
  /// "[2, 3, 8, 8]"
  std::string str() const;

  bool operator==(const Shape& other) const;
  bool operator!=(const Shape& other) const { return !(*this == other); }

 private:
  void assign(const std::int64_t* dims, std::size_t rank);
  int rank_ = 0;
  std::array<std::int64_t, kMaxRank> dims_{};
};

class Tensor {
 public:
  /// An undefined tensor (defined() is false): what grad() returns for "no gradient".
  Tensor() = default;

  /// A tensor of `shape` holding `values` (row-major; values.size() must equal
  /// shape.numel(), else std::invalid_argument naming both).
  Tensor(const Shape& shape, const std::vector<float>& values, bool requires_grad = false);
  /// The same, taking a pool buffer without copying.
  Tensor(const Shape& shape, Buffer values, bool requires_grad = false);
  /// The same from a braced list: Tensor(Shape{2}, {1.0f, 2.0f}).
  Tensor(const Shape& shape, std::initializer_list<float> values, bool requires_grad = false)
      : Tensor(shape, std::vector<float>(values), requires_grad) {}

  static Tensor zeros(const Shape& shape, bool requires_grad = false);
  static Tensor ones(const Shape& shape, bool requires_grad = false);
  static Tensor full(const Shape& shape, float value, bool requires_grad = false);
  static Tensor scalar(float value, bool requires_grad = false);

  bool defined() const { return impl_ != nullptr; }
  const Shape& shape() const;
  int rank() const { return shape().rank(); }
  std::int64_t numel() const { return shape().numel(); }

  /// Read-only and writable views of the storage (numel() floats, row-major). Writing into
  /// a tensor that an autodiff graph has used changes that graph's saved values: write only
  /// into leaves, between steps (as an optimiser does).
  const float* data() const;
  float* mutable_data();
  std::vector<float> to_vector() const;
  /// The value of a one-element tensor; std::invalid_argument otherwise.
  float item() const;

  bool requires_grad() const;
  /// Marks a leaf as a parameter/input to differentiate with respect to. Throws
  /// std::invalid_argument for a tensor produced by an operation (not a leaf).
  Tensor& set_requires_grad(bool value);
  /// True for tensors not produced by a differentiable operation.
  bool is_leaf() const;
  /// The operation that produced this tensor (null for leaves and for results computed
  /// without grad mode).
  const std::shared_ptr<Node>& grad_fn() const;

  /// The gradient accumulated by backward() into this leaf (undefined until then).
  Tensor grad() const;
  void zero_grad();

  /// Accumulates d(this)/d(leaf) into every leaf's grad(); `this` must have one element
  /// unless `grad_output` (same shape) is given. Frees nothing: the graph can be reused.
  void backward(const Tensor& grad_output = Tensor()) const;

  /// A new tensor with a copy of the values and no autodiff history.
  Tensor detach() const;
  /// Same storage, new shape with the same numel (differentiable).
  Tensor reshape(const Shape& shape) const;

  /// Identity of the underlying tensor (copies of a handle compare equal).
  const TensorImpl* id() const { return impl_.get(); }

 private:
  friend Tensor make_op_result(const Shape&, Buffer, std::shared_ptr<Node>, std::vector<Tensor>);
  friend Tensor share_storage(const Tensor&, const Shape&, std::shared_ptr<Node>);
  friend void accumulate_leaf_grad(const Tensor&, const Tensor&);
  std::shared_ptr<TensorImpl> impl_;
};

/// An autodiff node: the operation that produced one tensor from its inputs.
class Node {
 public:
  virtual ~Node() = default;
  /// The operation's name, used in error messages ("conv2d", "add", ...).
  virtual const char* name() const = 0;
  /// Gradients with respect to each input, given the gradient of the output; an undefined
  /// Tensor for an input that needs none. Written with differentiable operations.
  virtual std::vector<Tensor> backward(const Tensor& grad_output) = 0;

  /// The inputs the operation consumed (set by make_op_result).
  std::vector<Tensor> inputs;
};

/// Builds an operation's result: a tensor with `values`, and — when grad mode is on and an
/// input requires grad — `node` as its grad_fn with `inputs` recorded. For operation
/// implementers (ops.cpp and extensions).
Tensor make_op_result(const Shape& shape, Buffer values, std::shared_ptr<Node> node,
                      std::vector<Tensor> inputs);

/// Whether operations record autodiff graphs on this thread (on by default).
bool grad_mode_enabled();

/// Turns graph recording off (or on) on this thread for the guard's lifetime.
class GradModeGuard {
 public:
  explicit GradModeGuard(bool enabled);
  ~GradModeGuard();
  GradModeGuard(const GradModeGuard&) = delete;
  GradModeGuard& operator=(const GradModeGuard&) = delete;

 private:
  bool previous_;
};

/// Gradients of `outputs` with respect to `inputs`: the vector-Jacobian product
/// sum_k grad_outputs[k]^T d outputs[k] / d inputs[i] for each i.
///
/// `grad_outputs` may be empty when every output has one element (ones are used), else it
/// must hold one tensor per output with the output's shape. With `create_graph` the result
/// records its own graph, so it can be differentiated again (gradients of gradients);
/// without it the result is a plain tensor. An input the outputs do not depend on gets
/// zeros when `allow_unused`, else std::invalid_argument naming its position.
std::vector<Tensor> grad(const std::vector<Tensor>& outputs, const std::vector<Tensor>& inputs,
                         const std::vector<Tensor>& grad_outputs = {}, bool create_graph = false,
                         bool allow_unused = false);

}  // namespace ropes::nn
