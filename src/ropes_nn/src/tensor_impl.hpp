#pragma once
// Private: what a Tensor handle points to.
#include <initializer_list>
#include <memory>
#include <vector>

#include "ropes_nn/tensor.hpp"

namespace ropes::nn {

struct TensorImpl {
  Shape shape;
  std::shared_ptr<Buffer> storage;  // shape.numel() floats, shared by reshape
  bool requires_grad = false;
  std::shared_ptr<Node> grad_fn;  // null for leaves
  Tensor grad;                    // accumulated by Tensor::backward, leaves only
};

}  // namespace ropes::nn

namespace ropes::nn {
// Whether a node's backward should compute the gradient of its input `input`: the input
// requires one and, while grad() runs that backward, lies on a path to a tensor the call asks
// for (grad() keeps no other gradient, so a backward that skips the rest changes no result:
// J^T v through a decoder then computes no weight gradients).
bool input_grad_wanted(const Tensor& input);

// Whether an operation on `inputs` (a list or a vector of tensors) records a graph: grad
// mode is on and an input requires grad. Operations build their node (and the list of
// inputs) only then, so that a forward pass without grad mode allocates nothing beyond its
// results.
template <typename Inputs>
bool graph_needed(const Inputs& inputs) {
  if (!grad_mode_enabled())
    return false;
  for (const Tensor& t : inputs) {
    if (t.requires_grad())
      return true;
  }
  return false;
}
inline bool needs_graph(std::initializer_list<Tensor> inputs) {
  return graph_needed(inputs);
}
// A tensor that views `source`'s storage with another shape; records `node` (whose
// backward must undo the view) when grad mode is on and `source` requires grad.
Tensor share_storage(const Tensor& source, const Shape& shape, std::shared_ptr<Node> node);
// grad() that treats `inputs` as leaves: it neither runs their grad_fn nor looks past them,
// so it returns only the gradient through paths that do not pass through another input
// (what a node's own backward needs; the outer sweep handles the inputs' history).
std::vector<Tensor> grad_stopping_at_inputs(const std::vector<Tensor>& outputs,
                                            const std::vector<Tensor>& inputs,
                                            const std::vector<Tensor>& grad_outputs,
                                            bool create_graph);
// Adds to the benchmark FLOP counter (flop_count() in ops.hpp).
void add_flops(std::uint64_t flops);
}  // namespace ropes::nn
