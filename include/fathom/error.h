// fathom::Error: the one exception type of the library (ARCHITECTURE.md,
// "Habits"). It carries the file (or other subject) and the reason, and its
// what() reads "FILE: REASON".
#pragma once

#include <stdexcept>
#include <string>

namespace fathom {

class Error : public std::runtime_error {
public:
    Error(std::string subject, std::string reason)
        : std::runtime_error(subject.empty() ? reason : subject + ": " + reason),
          subject_(std::move(subject)),
          reason_(std::move(reason)) {}

    /// The file (or object) the error is about; may be empty.
    [[nodiscard]] const std::string& subject() const noexcept { return subject_; }
    /// What is wrong, without the subject.
    [[nodiscard]] const std::string& reason() const noexcept { return reason_; }

private:
    std::string subject_;
    std::string reason_;
};

}  // namespace fathom
