// SPDX-License-Identifier: MIT
// Typed errors of the horizonreg library (STYLE.md section 6). The library
// throws these and never prints or exits; only cli/ turns them into messages
// and exit codes.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace horizonreg {

// Base of every error the library throws.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Broken precondition: a programming error inside horizonreg or its caller.
class LogicError : public Error {
 public:
  using Error::Error;
};

// Invalid options or user input (a value out of range, an observer outside
// every DEM, a DEM that holds no data). The CLI maps it to exit code 2.
class InvalidArgument : public Error {
 public:
  using Error::Error;
};

// Environment or I/O failure: a file that cannot be opened or read. The
// message carries the stage and the file: "dem: cannot open 'x.tif': ...".
// The CLI maps it to exit code 2 (unreadable input).
class IoError : public Error {
 public:
  using Error::Error;
};

namespace internal {
// Collects a message with operator<< and throws E when it goes out of scope.
template <typename E>
class ThrowOnDestroy {
 public:
  ThrowOnDestroy(const char* file, int line, const char* cond) {
    stream_ << file << ":" << line << ": check failed: " << cond << ". ";
  }
  ThrowOnDestroy(const ThrowOnDestroy&) = delete;
  ThrowOnDestroy& operator=(const ThrowOnDestroy&) = delete;
  ~ThrowOnDestroy() noexcept(false) { throw E(stream_.str()); }
  template <typename T>
  ThrowOnDestroy& operator<<(const T& value) {
    stream_ << value;
    return *this;
  }

 private:
  std::ostringstream stream_;
};
}  // namespace internal

// Throws InvalidArgument "<field> = <value>; violated: <rule>" (STYLE.md
// section 5), e.g. ThrowField("HorizonOptions::azimuth_step_deg", 0.7,
// "360 / step is a whole number"). For every Options::Check().
template <typename T>
[[noreturn]] void ThrowField(const char* field, const T& value, const char* rule) {
  std::ostringstream m;
  m << field << " = " << value << "; violated: " << rule;
  throw InvalidArgument(m.str());
}

}  // namespace horizonreg

// HR_CHECK(cond) << "message": throws horizonreg::LogicError when cond is false.
#define HR_CHECK(cond) \
  if (cond) {          \
  } else               \
    ::horizonreg::internal::ThrowOnDestroy<::horizonreg::LogicError>(__FILE__, __LINE__, #cond)
