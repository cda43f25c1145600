# The cpkb image: the service (`cpkb serve`), migrations (`cpkb db upgrade`) and planner workers
# (`cpkb plan`, `cpkb bench`) all run from it; docker-compose.yml wires them together.
FROM python:3.11-slim

# A compiler for the packages that build from source (pybullet on some platforms).
RUN apt-get update \
    && apt-get install -y --no-install-recommends build-essential \
    && rm -rf /var/lib/apt/lists/*

ENV PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PYTHONUNBUFFERED=1

WORKDIR /app
# torch first and alone (its own layer; as in the Makefile), then the project.
ARG TORCH_SPEC=torch==2.13.0
RUN pip install "${TORCH_SPEC}"
COPY pyproject.toml README.md LICENSE ./
COPY cpkb ./cpkb
COPY server ./server
COPY client ./client
COPY planner ./planner
COPY surrogate ./surrogate
COPY migrations ./migrations
COPY deploy ./deploy
RUN pip install .

RUN useradd --create-home --uid 10001 cpkb && mkdir -p /runs && chown cpkb /runs
USER cpkb
EXPOSE 8000
CMD ["cpkb", "serve", "--host", "0.0.0.0", "--port", "8000"]
