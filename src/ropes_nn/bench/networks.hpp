#pragma once
// The paper's networks (appendix tables "Autoencoder1", "Autoencoder 2", "LDR") at a width
// multiplier, for the benchmark; bench/torch_peer.py builds the same ones in PyTorch.
#include <ropes_nn/layers.hpp>
#include <ropes_nn/ops.hpp>

#include <memory>

namespace ropes::nn::bench {

inline std::int64_t scaled(std::int64_t width, double multiplier) {
  return std::max<std::int64_t>(1, static_cast<std::int64_t>(width * multiplier));
}

// Conv(c_in -> w) then two ResBlockGN(w)
inline void add_stage(Sequential& s, std::int64_t c_in, std::int64_t w) {
  s.add(std::make_shared<Conv2d>(c_in, w, 3));
  s.add(std::make_shared<ResBlockGN>(w));
  s.add(std::make_shared<ResBlockGN>(w));
}

// AE1: [N, 1, 128, 128] -> [N, 1, 8, 8] -> [N, 1, 128, 128]
struct Ae1 {
  std::shared_ptr<Sequential> encoder = std::make_shared<Sequential>();
  std::shared_ptr<Sequential> decoder = std::make_shared<Sequential>();
  explicit Ae1(double m) {
    const std::int64_t w[4] = {scaled(64, m), scaled(128, m), scaled(256, m), scaled(512, m)};
    std::int64_t c = 1;
    for (int i = 0; i < 4; ++i) {
      add_stage(*encoder, c, w[i]);
      encoder->add(std::make_shared<Conv2d>(w[i], i < 3 ? w[i] : 1, 3, 2));
      encoder->add(std::make_shared<ReLU>());
      c = w[i];
    }
    c = 1;
    for (int i = 3; i >= 0; --i) {
      add_stage(*decoder, c, w[i]);
      decoder->add(std::make_shared<ConvTranspose2d>(w[i], w[i], 4, 2));
      decoder->add(std::make_shared<ReLU>());
      c = w[i];
    }
    decoder->add(std::make_shared<Conv2d>(c, 1, 3));
    decoder->add(std::make_shared<ReLU>());
    encoder->initialize(1);
    decoder->initialize(2);
  }
};

// LDR: [N, C, 8, 8] -> logit [N, 1]
struct Ldr {
  std::shared_ptr<Sequential> net = std::make_shared<Sequential>();
  explicit Ldr(std::int64_t c_in) {
    net->add(std::make_shared<Conv2d>(c_in, 32, 3, 1, Padding2d::valid()));
    net->add(std::make_shared<ReLU>());
    net->add(std::make_shared<Conv2d>(32, 64, 3, 1, Padding2d::valid()));
    net->add(std::make_shared<ReLU>());
    net->add(std::make_shared<Conv2d>(64, 128, 3, 1, Padding2d::valid()));
    net->add(std::make_shared<ReLU>());
    head1 = std::make_shared<Dense>(128 * 2 * 2, 128);
    head2 = std::make_shared<Dense>(128, 1);
    net->initialize(3);
    head1->initialize(3);
    head2->initialize(3);
  }
  Tensor forward(const Tensor& y) { return (*head2)(relu((*head1)(flatten((*net)(y))))); }
  std::vector<Tensor> parameters() const {
    std::vector<Tensor> p = net->parameters();
    for (auto* m : {head1.get(), head2.get()})
      for (const Tensor& t : m->parameters())
        p.push_back(t);
    return p;
  }
  std::shared_ptr<Dense> head1, head2;
};

// AE2: [N, C, 8, 8] -> z [N, D] -> [N, C, 8, 8]
struct Ae2 {
  std::shared_ptr<Sequential> encoder = std::make_shared<Sequential>();
  std::shared_ptr<Dense> to_latent, from_latent;
  std::shared_ptr<Sequential> decoder = std::make_shared<Sequential>();
  std::int64_t bottleneck;
  Ae2(double m, std::int64_t c_in, std::int64_t latent) {
    const std::int64_t w[3] = {scaled(64, m), scaled(128, m), scaled(256, m)};
    std::int64_t c = c_in;
    for (int i = 0; i < 3; ++i) {
      add_stage(*encoder, c, w[i]);
      encoder->add(std::make_shared<Conv2d>(w[i], w[i], 3, 2));
      encoder->add(std::make_shared<ReLU>());
      c = w[i];
    }
    bottleneck = w[2];
    to_latent = std::make_shared<Dense>(w[2], latent);
    from_latent = std::make_shared<Dense>(latent, w[2]);
    const std::int64_t d[3] = {scaled(512, m), scaled(256, m), scaled(128, m)};
    c = w[2];
    for (int i = 0; i < 3; ++i) {
      add_stage(*decoder, c, d[i]);
      decoder->add(std::make_shared<ConvTranspose2d>(d[i], d[i], 4, 2));
      decoder->add(std::make_shared<ReLU>());
      c = d[i];
    }
    decoder->add(std::make_shared<Conv2d>(c, c_in, 3));
    decoder->add(std::make_shared<ReLU>());
    encoder->initialize(4);
    to_latent->initialize(4);
    from_latent->initialize(5);
    decoder->initialize(5);
  }
  Tensor encode(const Tensor& y) { return (*to_latent)(flatten((*encoder)(y))); }
  Tensor decode(const Tensor& z) {
    const Tensor h = relu((*from_latent)(z));
    return (*decoder)(reshape(h, Shape{z.shape()[0], bottleneck, 1, 1}));
  }
  std::vector<Tensor> parameters() const {
    std::vector<Tensor> p;
    for (const Module* m : std::initializer_list<const Module*>{encoder.get(), to_latent.get(),
                                                                from_latent.get(), decoder.get()})
      for (const Tensor& t : m->parameters())
        p.push_back(t);
    return p;
  }
};

}  // namespace ropes::nn::bench
