#pragma once
/// @file layers.hpp
/// The layers of the ROPES networks (paper appendix, tables "Autoencoder1", "Autoencoder 2",
/// "LDR"), one header each under layers/: Conv2d, ConvTranspose2d, GroupNorm, Dense and
/// ResBlockGN. Kernels are initialised LeCun-normal (truncated normal, as Flax's default),
/// biases to zero. Shapes: images NCHW; Conv2d weight [O, C, KH, KW], ConvTranspose2d weight
/// [Cin, Cout, KH, KW] (PyTorch's layouts), Dense weight [in, out].
#include "ropes_nn/layers/conv2d.hpp"
#include "ropes_nn/layers/conv_transpose2d.hpp"
#include "ropes_nn/layers/dense.hpp"
#include "ropes_nn/layers/group_norm.hpp"
#include "ropes_nn/layers/res_block_gn.hpp"
