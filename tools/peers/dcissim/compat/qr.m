function varargout = qr(A, varargin)
% R = qr(A) with one output and a full A is MATLAB's upper-triangular factor R. Octave 7 returns
% LAPACK's packed result instead (R on and above the diagonal, Householder vectors below it): the
% authors' idenACN takes the lower-right block R22 of it, whose lower triangle would then hold
% Householder vectors, and its SVD gives a wrong observability matrix. This stand-in returns
% triu() of that result, MATLAB's R; every other call goes to the built-in qr unchanged (msid's own
% code).
  if nargout <= 1 && ~issparse(A)
    varargout{1} = triu(builtin('qr', A, varargin{:}));
    return;
  end
  varargout = cell(1, max(nargout, 1));
  [varargout{:}] = builtin('qr', A, varargin{:});
end
