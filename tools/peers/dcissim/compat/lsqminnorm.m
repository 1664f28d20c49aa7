function X = lsqminnorm(A, B, tol, varargin)
% X = lsqminnorm(A, B [, tol]): the minimum-norm least-squares solution of A X = B, as MATLAB's:
% a complete orthogonal decomposition (QR with column pivoting, then an RQ of the leading rows),
% the rank being the count of |R(k,k)| above tol, by default max(size(A)) * eps(|R(1,1)|).
% A stand-in for Octave, which has no lsqminnorm (msid's own code). Extra flags ('warn',
% 'nowarn') are accepted and ignored.
  [m, n] = size(A);
  if m == 0 || n == 0
    X = zeros(n, size(B, 2));
    return;
  end
  [Q, R, p] = qr(A, 0);                 % A(:, p) = Q R, |diag R| non-increasing
  d = abs(diag(R));
  if nargin < 3 || isempty(tol) || ischar(tol)
    tol = max(m, n) * eps(d(1));
  end
  r = sum(d > tol);
  X = zeros(n, size(B, 2));
  if r == 0
    return;
  end
  % R(1:r, :) = T' Z' with Z orthonormal (n x r): A(:, p) = Q(:, 1:r) T' Z' + (part below tol)
  [Z, T] = qr(R(1:r, :)', 0);
  Y = Z * (T' \ (Q(:, 1:r)' * B));
  X(p, :) = Y;
end
