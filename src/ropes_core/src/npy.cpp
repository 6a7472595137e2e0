#include "ropes_core/npy.hpp"

#include "ropes_core/file_io.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>

#include "file_errors.hpp"

namespace ropes::core {

namespace {

constexpr char kMagic[] = "\x93NUMPY";
constexpr std::size_t kMagicSize = 6;

using detail::fail;
using detail::FilePtr;

// the header dictionary, e.g. {'descr': '<f4', 'fortran_order': False, 'shape': (3, 4), }
class HeaderParser {
 public:
  HeaderParser(const std::string& text, const std::string& name) : text_(text), name_(name) {}

  void parse(NpyHeader* header) {
    bool have_descr = false, have_order = false, have_shape = false;
    expect('{');
    while (true) {
      skip_space();
      if (peek() == '}')
        break;
      const std::string key = quoted();
      expect(':');
      if (key == "descr") {
        header->dtype = descr_to_dtype(quoted());
        have_descr = true;
      } else if (key == "fortran_order") {
        if (word() != "False") {
          fail(name_, "fortran_order is True; expected a C-order (row-major) array");
        }
        have_order = true;
      } else if (key == "shape") {
        header->shape = tuple();
        have_shape = true;
      } else {
        fail(name_, "unexpected key '" + key +
                        "' in the .npy header; expected descr, "
                        "fortran_order and shape");
      }
      skip_space();
      if (peek() == ',')
        ++pos_;
    }
    ++pos_;  // '}'
    if (!have_descr || !have_order || !have_shape) {
      fail(name_, "the .npy header lacks one of descr, fortran_order, shape: '" + text_ + "'");
    }
  }

 private:
  char peek() {
    if (pos_ >= text_.size())
      fail(name_, "the .npy header ends early: '" + text_ + "'");
    return text_[pos_];
  }
  void skip_space() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_])))
      ++pos_;
  }
  void expect(char c) {
    skip_space();
    if (peek() != c) {
      fail(name_, std::string("malformed .npy header at byte ") + std::to_string(pos_) +
                      ": expected '" + c + "' in '" + text_ + "'");
    }
    ++pos_;
  }
  std::string quoted() {
    skip_space();
    const char quote = peek();
    if (quote != '\'' && quote != '"')
      expect('\'');
    const std::size_t end = text_.find(quote, pos_ + 1);
    if (end == std::string::npos)
      fail(name_, "unterminated string in the .npy header");
    std::string s = text_.substr(pos_ + 1, end - pos_ - 1);
    pos_ = end + 1;
    return s;
  }
  std::string word() {
    skip_space();
    const std::size_t begin = pos_;
    while (pos_ < text_.size() && std::isalpha(static_cast<unsigned char>(text_[pos_])))
      ++pos_;
    return text_.substr(begin, pos_ - begin);
  }
  std::vector<std::int64_t> tuple() {
    std::vector<std::int64_t> dims;
    expect('(');
    while (true) {
      skip_space();
      if (peek() == ')')
        break;
      if (!std::isdigit(static_cast<unsigned char>(peek()))) {
        fail(name_, "shape holds '" + text_.substr(pos_, 8) + "'; expected non-negative integers");
      }
      std::int64_t value = 0;
      while (pos_ < text_.size() && std::isdigit(static_cast<unsigned char>(text_[pos_]))) {
        const int digit = text_[pos_++] - '0';
        if (value > (std::numeric_limits<std::int64_t>::max() - digit) / 10) {
          fail(name_, "a dimension in the .npy shape overflows 64 bits");
        }
        value = value * 10 + digit;
      }
      dims.push_back(value);
      if (static_cast<int>(dims.size()) > kNpyMaxRank) {
        fail(name_, "the .npy shape has more than " + std::to_string(kNpyMaxRank) + " dimensions");
      }
      skip_space();
      if (peek() == ',')
        ++pos_;
    }
    ++pos_;  // ')'
    return dims;
  }
  DType descr_to_dtype(const std::string& descr) {
    if (descr == "|u1" || descr == "<u1" || descr == "u1")
      return DType::kU8;
    if (descr == "<i4")
      return DType::kI32;
    if (descr == "<i8")
      return DType::kI64;
    if (descr == "<f4")
      return DType::kF32;
    if (descr == "<f8")
      return DType::kF64;
    fail(name_,
         "dtype '" + descr + "' is not supported; expected little-endian u1, <i4, <i8, <f4 or <f8");
  }

  const std::string& text_;
  const std::string& name_;
  std::size_t pos_ = 0;
};

const char* dtype_descr(DType dtype) {
  switch (dtype) {
    case DType::kU8:
      return "|u1";
    case DType::kI32:
      return "<i4";
    case DType::kI64:
      return "<i8";
    case DType::kF32:
      return "<f4";
    case DType::kF64:
      return "<f8";
  }
  return "?";
}

// element count * itemsize, or a FileFormatError when it overflows
std::uint64_t byte_count(const std::vector<std::int64_t>& shape, DType dtype,
                         const std::string& name) {
  for (std::int64_t d : shape) {
    if (d < 0)
      fail(name, "negative dimension " + std::to_string(d));
  }
  std::uint64_t count = 0;
  if (!checked_byte_count(dtype, shape, &count)) {
    fail(name, "the array's byte count overflows 64 bits");
  }
  return count;
}

std::string shape_string(const std::vector<std::int64_t>& shape) {
  std::ostringstream s;
  s << '(';
  for (std::size_t i = 0; i < shape.size(); ++i)
    s << (i ? ", " : "") << shape[i];
  s << (shape.size() == 1 ? ",)" : ")");
  return s.str();
}

}  // namespace

std::int64_t NpyArray::element_count() const {
  std::int64_t n = 1;
  for (std::int64_t d : shape)
    n *= d;
  return n;
}

NpyHeader parse_npy_header(const std::uint8_t* bytes, std::size_t size, const std::string& name) {
  // magic, version, header length
  if (size < kMagicSize + 2 || std::memcmp(bytes, kMagic, kMagicSize) != 0) {
    fail(name, "not a .npy file (no \\x93NUMPY magic string at the start)");
  }
  const int major = bytes[6];
  const int minor = bytes[7];
  std::size_t length_bytes = 0;
  if (major == 1 && minor == 0) {
    length_bytes = 2;
  } else if ((major == 2 || major == 3) && minor == 0) {
    length_bytes = 4;
  } else {
    fail(name, ".npy format version " + std::to_string(major) + "." + std::to_string(minor) +
                   " is not supported; expected 1.0, 2.0 or 3.0");
  }
  const std::size_t prefix = kMagicSize + 2 + length_bytes;
  if (size < prefix)
    fail(name, "the file ends inside the .npy header");
  std::uint64_t header_length = 0;
  for (std::size_t i = 0; i < length_bytes; ++i) {
    header_length |= static_cast<std::uint64_t>(bytes[kMagicSize + 2 + i]) << (8 * i);
  }
  if (header_length > kNpyMaxHeaderBytes) {
    fail(name, "the .npy header claims " + std::to_string(header_length) +
                   " bytes; expected at most " + std::to_string(kNpyMaxHeaderBytes));
  }
  if (size < prefix + header_length) {
    fail(name, "the file ends inside the .npy header (" + std::to_string(size) +
                   " bytes, header needs " + std::to_string(prefix + header_length) + ")");
  }

  // the dictionary
  const std::string text(reinterpret_cast<const char*>(bytes + prefix), header_length);
  NpyHeader header;
  HeaderParser(text, name).parse(&header);
  header.data_offset = prefix + header_length;
  header.data_bytes = byte_count(header.shape, header.dtype, name);
  return header;
}

NpyHeader read_npy_header(const std::filesystem::path& path) {
  const std::string name = path.string();
  FilePtr file(std::fopen(name.c_str(), "rb"));
  if (!file)
    fail(name, std::string("cannot open: ") + std::strerror(errno));
  std::vector<std::uint8_t> head(kMagicSize + 2 + 4 + kNpyMaxHeaderBytes);
  head.resize(std::fread(head.data(), 1, head.size(), file.get()));
  std::error_code ec;
  const std::uintmax_t file_size = std::filesystem::file_size(path, ec);
  if (ec)
    fail(name, "cannot stat: " + ec.message());
  NpyHeader header = parse_npy_header(head.data(), head.size(), name);
  if (file_size != header.data_offset + header.data_bytes) {
    fail(name,
         "holds " +
             std::to_string(file_size - std::min<std::uintmax_t>(file_size, header.data_offset)) +
             " data bytes; the header's " + std::string(dtype_name(header.dtype)) + " " +
             shape_string(header.shape) + " needs " + std::to_string(header.data_bytes));
  }
  return header;
}

NpyArray parse_npy(const std::uint8_t* bytes, std::size_t size, const std::string& name) {
  const NpyHeader header = parse_npy_header(bytes, size, name);
  const std::uint64_t available = size - header.data_offset;
  if (available != header.data_bytes) {
    fail(name, "holds " + std::to_string(available) + " data bytes; the header's " +
                   dtype_name(header.dtype) + " " + shape_string(header.shape) + " needs " +
                   std::to_string(header.data_bytes));
  }
  NpyArray array;
  array.dtype = header.dtype;
  array.shape = header.shape;
  array.data.assign(bytes + header.data_offset, bytes + size);
  return array;
}

NpyArray read_npy(const std::filesystem::path& path) {
  const std::string name = path.string();
  // the header first: its byte count bounds the allocation before anything is read
  const NpyHeader header = read_npy_header(path);
  FilePtr file(std::fopen(name.c_str(), "rb"));
  if (!file)
    fail(name, std::string("cannot open: ") + std::strerror(errno));
  NpyArray array;
  array.dtype = header.dtype;
  array.shape = header.shape;
  array.data.resize(header.data_bytes);
  if (std::fseek(file.get(), static_cast<long>(header.data_offset), SEEK_SET) != 0 ||
      std::fread(array.data.data(), 1, array.data.size(), file.get()) != array.data.size()) {
    fail(name, "could not read the " + std::to_string(header.data_bytes) + " data bytes");
  }
  return array;
}

std::vector<std::uint8_t> serialize_npy(const NpyArray& array) {
  const std::uint64_t expected = byte_count(array.shape, array.dtype, "serialize_npy");
  if (array.data.size() != expected) {
    throw std::invalid_argument("serialize_npy: " + std::to_string(array.data.size()) +
                                " data bytes for a " + dtype_name(array.dtype) +
                                " array of shape " + shape_string(array.shape) + "; expected " +
                                std::to_string(expected));
  }
  std::string dict = std::string("{'descr': '") + dtype_descr(array.dtype) +
                     "', 'fortran_order': False, 'shape': " + shape_string(array.shape) + ", }";
  // pad with spaces so the data starts on a 64-byte boundary; the header ends in '\n'
  const bool v2 = dict.size() + 1 + kMagicSize + 2 + 2 > 65535;
  const std::size_t prefix = kMagicSize + 2 + (v2 ? 4 : 2);
  const std::size_t total = prefix + dict.size() + 1;
  dict.append((64 - total % 64) % 64, ' ');
  dict.push_back('\n');

  std::vector<std::uint8_t> out(kMagic, kMagic + kMagicSize);
  out.push_back(v2 ? 2 : 1);
  out.push_back(0);
  for (std::size_t i = 0; i < (v2 ? 4u : 2u); ++i) {
    out.push_back(static_cast<std::uint8_t>(dict.size() >> (8 * i)));
  }
  out.insert(out.end(), dict.begin(), dict.end());
  out.insert(out.end(), array.data.begin(), array.data.end());
  return out;
}

void write_npy(const std::filesystem::path& path, const NpyArray& array) {
  const std::vector<std::uint8_t> bytes = serialize_npy(array);
  write_file_atomically(path, bytes.data(), bytes.size());
}

}  // namespace ropes::core
