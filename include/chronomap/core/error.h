#pragma once
/// @file
/// The one exception hierarchy of chronomap. The library never prints and never exits:
/// it throws one of these, and the command line turns them into a message and an exit code.

#include <exception>
#include <stdexcept>
#include <string>

namespace chronomap {

/// Base of every error chronomap throws on purpose.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The caller asked for something impossible (bad settings, bad arguments). CLI exit code 2.
class UsageError : public Error {
 public:
  using Error::Error;
};

/// The input data is wrong: malformed files, impossible poses, empty datasets. CLI exit code 1.
class DataError : public Error {
 public:
  using Error::Error;
};

/// A file is not a valid file of its format (truncated, corrupt, wrong magic, newer version).
class FormatError : public DataError {
 public:
  using DataError::DataError;
};

/// The operating system refused a file operation (missing file, permission, full disk).
class IoError : public Error {
 public:
  using Error::Error;
};

/// What the command line says about a failure: its exit code and its one-line message.
struct ErrorReport {
  int exit_code = 1;  ///< 2 for bad usage (UsageError), 1 for everything else
  std::string message;
};
/// The report of an exception (non-null): a chronomap Error's own message; for a file operation the
/// operating system refused, the file and the system's word for the problem; "out of memory";
/// "internal error: ..." for anything else.
ErrorReport describeError(const std::exception_ptr& error);

}  // namespace chronomap
